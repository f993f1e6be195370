//! [`GpuError`], what the building blocks report.

/// A GPU operation that could not run: no adapter, a refused device, a buffer beyond the
/// device's limits, a failed read-back, or an error the device reported.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("wgpu backend ({stage}): {message}")]
pub struct GpuError {
    /// Where it failed: `adapter`, `device`, `pipelines`, `buffers` or `read-back`.
    pub stage: &'static str,
    /// What went wrong.
    pub message: String,
}

impl GpuError {
    /// An error at `stage`.
    pub fn new(stage: &'static str, message: impl Into<String>) -> Self {
        Self {
            stage,
            message: message.into(),
        }
    }
}
