//! Frames: the sorted distinct training timestamps, and the history of a query time.

use thiserror::Error;

/// Sorted, distinct, finite training times t_0 < t_1 < ... < t_{T-1}.
#[derive(Debug, Clone, PartialEq)]
pub struct Frames {
    times: Vec<f32>,
}

/// Bad frame times.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum FramesError {
    /// The list of times is empty.
    #[error("frames: no training times")]
    Empty,
    /// A time is NaN or infinite.
    #[error("frames: time[{index}] = {time} is not finite")]
    NonFinite {
        /// Its index in the list.
        index: usize,
        /// The time.
        time: f32,
    },
    /// A time is not greater than the one before it (unsorted or repeated).
    #[error("frames: time[{index}] = {time} does not exceed the previous time")]
    NotIncreasing {
        /// Its index in the list.
        index: usize,
        /// The time.
        time: f32,
    },
}

/// The history of a query: frames k1 > k2 > k3 (only the first `len` are meaningful).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct History {
    /// Frame indices into [`Frames`], latest first; entries from `len` on are unused.
    pub frames: [usize; 3],
    /// h, the number of history frames (0..=3).
    pub len: usize,
}

impl History {
    /// The history frames, latest first.
    pub fn frames(&self) -> &[usize] {
        &self.frames[..self.len]
    }
}

impl Frames {
    /// Frames from times already sorted and distinct.
    pub fn new(times: Vec<f32>) -> Result<Self, FramesError> {
        if times.is_empty() {
            return Err(FramesError::Empty);
        }
        for (index, &time) in times.iter().enumerate() {
            if !time.is_finite() {
                return Err(FramesError::NonFinite { index, time });
            }
            if index > 0 && time <= times[index - 1] {
                return Err(FramesError::NotIncreasing { index, time });
            }
        }
        Ok(Self { times })
    }

    /// Frames from any timestamps (e.g. one per training image): sorted, duplicates merged.
    pub fn from_timestamps(times: impl IntoIterator<Item = f32>) -> Result<Self, FramesError> {
        let mut times: Vec<f32> = times.into_iter().collect();
        if let Some(index) = times.iter().position(|t| !t.is_finite()) {
            return Err(FramesError::NonFinite {
                index,
                time: times[index],
            });
        }
        times.sort_by(f32::total_cmp);
        times.dedup();
        Self::new(times)
    }

    /// T, the number of frames.
    pub fn len(&self) -> usize {
        self.times.len()
    }

    /// Always false (frames are never empty); present for API symmetry.
    pub fn is_empty(&self) -> bool {
        self.times.is_empty()
    }

    /// The frame times.
    pub fn times(&self) -> &[f32] {
        &self.times
    }

    /// The frame whose time is exactly `t`, if any.
    pub fn frame_of(&self, t: f32) -> Option<usize> {
        // Numeric comparison (so -0.0 finds 0.0); NaN matches nothing.
        let k = self.position(t);
        (k < self.times.len() && self.times[k] == t).then_some(k)
    }

    /// Number of frames strictly before `t`: the query sits at this frame position.
    pub fn position(&self, t: f32) -> usize {
        self.times.partition_point(|&x| x < t)
    }

    /// The history of a query at `t`: latest available frames strictly before `t`, each within
    /// `max_gap` frames of the one after it (the query counts as sitting at
    /// [`Frames::position`]). `available(k)` says whether frame k can be used.
    pub fn history(&self, t: f32, max_gap: usize, available: impl Fn(usize) -> bool) -> History {
        let mut out = History {
            frames: [0; 3],
            len: 0,
        };
        let mut after = self.position(t);
        while out.len < 3 {
            let lowest = after.saturating_sub(max_gap);
            let Some(k) = (lowest..after).rev().find(|&k| available(k)) else {
                break;
            };
            out.frames[out.len] = k;
            out.len += 1;
            after = k;
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn history_respects_validity_and_gaps() {
        let frames = Frames::new((0..10).map(|k| k as f32 / 10.0).collect()).unwrap();
        let all = |_| true;
        assert_eq!(frames.history(0.0, 3, all).len, 0);
        assert_eq!(frames.history(0.5, 3, all).frames(), &[4, 3, 2]);
        // Between frames 4 and 5: the query sits at position 5.
        assert_eq!(frames.history(0.45, 3, all).frames(), &[4, 3, 2]);
        // Beyond the last frame.
        assert_eq!(frames.history(7.0, 3, all).frames(), &[9, 8, 7]);
        // Frames 2 and 3 invalid: 4 -> 1 is a gap of 3, allowed; with max_gap 2 it is not.
        let valid = |k: usize| k != 2 && k != 3;
        assert_eq!(frames.history(0.5, 3, valid).frames(), &[4, 1, 0]);
        assert_eq!(frames.history(0.5, 2, valid).frames(), &[4]);
        // Latest valid frame too far from the query.
        assert_eq!(frames.history(0.9, 3, |k| k < 5).len, 0);
    }

    #[test]
    fn timestamps_are_sorted_and_deduplicated() {
        let frames = Frames::from_timestamps([0.5, 0.0, 0.5, 0.25]).unwrap();
        assert_eq!(frames.times(), &[0.0, 0.25, 0.5]);
        assert_eq!(frames.frame_of(0.25), Some(1));
        assert_eq!(frames.frame_of(0.3), None);
        assert_eq!(frames.frame_of(-0.0), Some(0));
        assert_eq!(frames.frame_of(f32::NAN), None);
        assert_eq!(frames.frame_of(7.0), None);
        assert_eq!(
            Frames::new(vec![0.0, 0.0]),
            Err(FramesError::NotIncreasing {
                index: 1,
                time: 0.0
            })
        );
        assert!(matches!(
            Frames::from_timestamps([f32::NAN]),
            Err(FramesError::NonFinite { .. })
        ));
        assert_eq!(Frames::new(vec![]), Err(FramesError::Empty));
    }
}
