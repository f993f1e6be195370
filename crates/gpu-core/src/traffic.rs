//! What crosses between the host and a device, counted by a backend as it records the work:
//! [`Traffic`], a snapshot of the running totals that [`crate::Rasterizer::traffic`] returns.

use std::fmt;

use serde::{Deserialize, Serialize};

/// Running totals of the host–device traffic and the work submitted on one device context
/// since it was made. Take two snapshots and [`Traffic::since`] for what happened between them.
///
/// Counted where the backend records the work, not measured by the driver: bytes written into
/// device buffers by the host (buffer creation with contents, queue writes), bytes copied back
/// into mapped staging buffers, command submissions, host waits on the device, compute
/// dispatches, buffers and bind groups created.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Traffic {
    /// Bytes uploaded from the host into device buffers.
    pub bytes_up: u64,
    /// Bytes read back from the device into host memory.
    pub bytes_down: u64,
    /// Command buffers submitted (`Queue::submit` calls).
    pub submits: u64,
    /// Times the host blocked until the device finished (read-backs).
    pub waits: u64,
    /// Compute dispatches recorded.
    pub dispatches: u64,
    /// Device buffers created (storage, uniform and staging).
    pub buffers_created: u64,
    /// Bind groups created.
    pub bind_groups_created: u64,
}

impl Traffic {
    /// What happened between `earlier` and `self` (field by field, saturating at zero).
    #[must_use]
    pub fn since(&self, earlier: &Traffic) -> Traffic {
        Traffic {
            bytes_up: self.bytes_up.saturating_sub(earlier.bytes_up),
            bytes_down: self.bytes_down.saturating_sub(earlier.bytes_down),
            submits: self.submits.saturating_sub(earlier.submits),
            waits: self.waits.saturating_sub(earlier.waits),
            dispatches: self.dispatches.saturating_sub(earlier.dispatches),
            buffers_created: self.buffers_created.saturating_sub(earlier.buffers_created),
            bind_groups_created: self
                .bind_groups_created
                .saturating_sub(earlier.bind_groups_created),
        }
    }

    /// Every field divided by `n` (the mean per call or per iteration); `n = 0` gives zeros.
    pub fn per(&self, n: u64) -> TrafficRate {
        let d = |v: u64| if n == 0 { 0.0 } else { v as f64 / n as f64 };
        TrafficRate {
            bytes_up: d(self.bytes_up),
            bytes_down: d(self.bytes_down),
            submits: d(self.submits),
            waits: d(self.waits),
            dispatches: d(self.dispatches),
            buffers_created: d(self.buffers_created),
            bind_groups_created: d(self.bind_groups_created),
        }
    }
}

/// [`Traffic`] per call or per iteration (means, from [`Traffic::per`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct TrafficRate {
    /// Bytes uploaded from the host into device buffers.
    pub bytes_up: f64,
    /// Bytes read back from the device into host memory.
    pub bytes_down: f64,
    /// Command buffers submitted.
    pub submits: f64,
    /// Host waits on the device.
    pub waits: f64,
    /// Compute dispatches recorded.
    pub dispatches: f64,
    /// Device buffers created.
    pub buffers_created: f64,
    /// Bind groups created.
    pub bind_groups_created: f64,
}

impl fmt::Display for TrafficRate {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{:.1} KiB up, {:.1} KiB down, {:.1} submits, {:.1} waits, {:.1} dispatches, \
             {:.1} buffers and {:.1} bind groups created",
            self.bytes_up / 1024.0,
            self.bytes_down / 1024.0,
            self.submits,
            self.waits,
            self.dispatches,
            self.buffers_created,
            self.bind_groups_created
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn since_and_per_take_differences_and_means() {
        let a = Traffic {
            bytes_up: 100,
            bytes_down: 10,
            submits: 1,
            waits: 1,
            dispatches: 5,
            buffers_created: 3,
            bind_groups_created: 2,
        };
        let b = Traffic {
            bytes_up: 300,
            bytes_down: 50,
            submits: 5,
            waits: 3,
            dispatches: 25,
            buffers_created: 7,
            bind_groups_created: 6,
        };
        let d = b.since(&a);
        assert_eq!(d.bytes_up, 200);
        assert_eq!(d.bytes_down, 40);
        assert_eq!(d.dispatches, 20);
        assert_eq!(a.since(&b), Traffic::default());
        let r = d.per(4);
        assert_eq!(r.bytes_up, 50.0);
        assert_eq!(r.submits, 1.0);
        assert_eq!(r.bind_groups_created, 1.0);
        assert_eq!(d.per(0), TrafficRate::default());
    }
}
