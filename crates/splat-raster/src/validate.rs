//! Input validation shared by the backends: lengths, SH degrees, camera and background values,
//! and the per-pixel gradient images of the backward pass.

use rayon::prelude::*;

use crate::camera::Camera;
use crate::error::RasterError;
use crate::gaussians::GaussiansView;
use crate::options::RenderOptions;
use crate::output::{ForwardOutput, PixelGrads};

/// Checks the inputs and returns the active SH degree.
pub(crate) fn validate(
    g: &GaussiansView<'_>,
    cam: &Camera,
    opts: &RenderOptions,
) -> Result<u32, RasterError> {
    if g.sh_degree > 3 {
        return Err(RasterError::ShDegree(g.sh_degree));
    }
    let n = g.len();
    let checks = [
        ("log_scales", g.log_scales.len(), n),
        ("rotations", g.rotations.len(), n),
        ("opacity_logits", g.opacity_logits.len(), n),
        ("sh", g.sh.len(), n * g.sh_stride()),
    ];
    for (field, got, expected) in checks {
        if got != expected {
            return Err(RasterError::LengthMismatch {
                field,
                got,
                expected,
            });
        }
    }
    if n > u32::MAX as usize {
        return Err(RasterError::LengthMismatch {
            field: "means",
            got: n,
            expected: u32::MAX as usize,
        });
    }
    let active = opts.sh_degree.unwrap_or(g.sh_degree);
    if active > g.sh_degree {
        return Err(RasterError::ActiveShDegree {
            requested: active,
            available: g.sh_degree,
        });
    }
    if cam.width == 0 || cam.height == 0 {
        return Err(RasterError::EmptyImage {
            width: cam.width,
            height: cam.height,
        });
    }
    for (field, value) in [("fx", cam.fx), ("fy", cam.fy)] {
        if !(value.is_finite() && value > 0.0) {
            return Err(RasterError::BadCamera {
                field,
                value,
                why: "must be finite and positive",
            });
        }
    }
    let (rotation, translation) = (cam.rotation.to_cols_array(), cam.translation.to_array());
    let finite: [(&str, &[f32]); 4] = [
        ("cx", &[cam.cx]),
        ("cy", &[cam.cy]),
        ("rotation", &rotation),
        ("translation", &translation),
    ];
    for (field, values) in finite {
        if let Some(&value) = values.iter().find(|v| !v.is_finite()) {
            return Err(RasterError::BadCamera {
                field,
                value,
                why: "must be finite",
            });
        }
    }
    for (channel, &value) in opts.background.iter().enumerate() {
        if !value.is_finite() {
            return Err(RasterError::BadBackground { channel, value });
        }
    }
    Ok(active)
}

/// Pixels per parallel task of [`check_pixels`].
const CHECK_CHUNK: usize = 1 << 14;

/// Checks a per-pixel gradient image's length and finiteness.
pub(crate) fn check_pixels<T: Copy + Sync>(
    field: &'static str,
    data: &[T],
    expected: usize,
    finite: impl Fn(T) -> bool + Sync,
) -> Result<(), RasterError> {
    if data.len() != expected {
        return Err(RasterError::GradientLength {
            field,
            got: data.len(),
            expected,
        });
    }
    // In parallel, without stopping early (a branch-free sweep the compiler vectorises); the
    // first bad pixel is looked for only when there is one.
    let all_finite = data
        .par_chunks(CHECK_CHUNK)
        .all(|chunk| chunk.iter().fold(true, |ok, &v| ok & finite(v)));
    if all_finite {
        return Ok(());
    }
    match data.iter().position(|&v| !finite(v)) {
        Some(pixel) => Err(RasterError::NonFiniteGradient { field, pixel }),
        None => Ok(()),
    }
}

/// Checks the inputs of a backward pass: those of [`validate`], that `fwd` came from a forward
/// pass on the same Gaussians, camera size, SH degrees and background, and the pixel gradient
/// images (length and finiteness). Returns the active SH degree. Which backend ran the forward
/// pass is for the caller to check.
pub(crate) fn validate_backward(
    g: &GaussiansView<'_>,
    cam: &Camera,
    opts: &RenderOptions,
    fwd: &ForwardOutput,
    d: PixelGrads<'_>,
) -> Result<u32, RasterError> {
    let active = validate_backward_state(g, cam, opts, fwd)?;
    let npix = cam.pixel_count();
    check_pixels("d_color", d.color, npix, |c: [f32; 3]| {
        c.iter().all(|v| v.is_finite())
    })?;
    if let Some(alpha) = d.alpha {
        check_pixels("d_alpha", alpha, npix, f32::is_finite)?;
    }
    if let Some(depth) = d.depth {
        check_pixels("d_depth", depth, npix, f32::is_finite)?;
    }
    Ok(active)
}

/// The checks of [`validate_backward`] but the pixel gradients': the inputs, and the forward
/// output made from them (a backward whose pixel gradients are on the device checks those
/// where they are made).
pub(crate) fn validate_backward_state(
    g: &GaussiansView<'_>,
    cam: &Camera,
    opts: &RenderOptions,
    fwd: &ForwardOutput,
) -> Result<u32, RasterError> {
    let active = validate(g, cam, opts)?;
    let st = &fwd.state;
    let mismatch = |what: String| Err(RasterError::ForwardMismatch(what));
    if st.n_gaussians != g.len() {
        return mismatch(format!(
            "forward saw {} Gaussians, backward got {}",
            st.n_gaussians,
            g.len()
        ));
    }
    if (fwd.width, fwd.height) != (cam.width, cam.height) {
        return mismatch(format!(
            "forward image is {}x{}, camera is {}x{}",
            fwd.width, fwd.height, cam.width, cam.height
        ));
    }
    if st.sh_degree != g.sh_degree || st.active_degree != active {
        return mismatch("SH degree differs".into());
    }
    if st.background.map(f32::to_bits) != opts.background.map(f32::to_bits) {
        return mismatch("background differs".into());
    }
    Ok(active)
}
