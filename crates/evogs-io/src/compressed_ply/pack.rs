//! The quantisers of the compressed PLY: values normalised to a chunk's `[min, max]`, unsigned
//! normalised integers packed as 11-10-11 and 8-8-8-8 bits into one `u32`, unit quaternions as
//! 2 + 10 + 10 + 10 bits, and higher SH coefficients as one byte each.
//!
//! Each packer is followed by its exact inverse as PlayCanvas's readers decode it; the module's
//! tests bound the round-trip error of each.

use std::f32::consts::FRAC_1_SQRT_2;

/// The largest integer of `bits` bits, as used by [`pack_unorm`].
fn unorm_max(bits: u32) -> u32 {
    (1u32 << bits) - 1
}

/// `v` in [0, 1] as the nearest of `2^bits` levels (`floor(v · (2^bits − 1) + 0.5)`, clamped;
/// NaN gives 0).
pub fn pack_unorm(v: f32, bits: u32) -> u32 {
    let t = unorm_max(bits) as f32;
    // `as` saturates and maps NaN to 0.
    ((v * t + 0.5).floor().clamp(0.0, t)) as u32
}

/// The low `bits` bits of `word` as a value in [0, 1].
pub fn unpack_unorm(word: u32, bits: u32) -> f32 {
    let t = unorm_max(bits);
    (word & t) as f32 / t as f32
}

/// `x` as a fraction of the range `[min, max]`: 0 at or below `min`, 1 at or above `max`, and 0
/// for a range narrower than 1e-5 (PlayCanvas's writer's rule, kept so files decode alike).
pub fn normalise(x: f32, min: f32, max: f32) -> f32 {
    if x <= min {
        0.0
    } else if x >= max {
        1.0
    } else if max - min < 1e-5 {
        0.0
    } else {
        (x - min) / (max - min)
    }
}

/// The inverse of [`normalise`]: `min · (1 − t) + max · t`.
pub fn lerp(min: f32, max: f32, t: f32) -> f32 {
    min * (1.0 - t) + max * t
}

/// Three values in [0, 1] as 11 bits (bits 21..32), 10 bits (11..21) and 11 bits (0..11).
pub fn pack_11_10_11([x, y, z]: [f32; 3]) -> u32 {
    (pack_unorm(x, 11) << 21) | (pack_unorm(y, 10) << 11) | pack_unorm(z, 11)
}

/// The inverse of [`pack_11_10_11`].
pub fn unpack_11_10_11(word: u32) -> [f32; 3] {
    [
        unpack_unorm(word >> 21, 11),
        unpack_unorm(word >> 11, 10),
        unpack_unorm(word, 11),
    ]
}

/// Four values in [0, 1] as 8 bits each, the first in the highest byte.
pub fn pack_8888(v: [f32; 4]) -> u32 {
    v.iter()
        .fold(0u32, |word, &c| (word << 8) | pack_unorm(c, 8))
}

/// The inverse of [`pack_8888`].
pub fn unpack_8888(word: u32) -> [f32; 4] {
    [24, 16, 8, 0].map(|shift| unpack_unorm(word >> shift, 8))
}

/// A quaternion in the file's order (`rot_0..rot_3`, i.e. `w, x, y, z`) as 32 bits: normalised
/// (a zero quaternion becomes the identity), the sign flipped so that the component of largest
/// magnitude is positive, that component's index in the top 2 bits and the other three, each in
/// `[−1/√2, 1/√2]`, as 10 bits in index order below it.
pub fn pack_rotation(q: [f32; 4]) -> u32 {
    let n = q.iter().map(|v| v * v).sum::<f32>().sqrt();
    let mut a = if n > 0.0 {
        q.map(|v| v / n)
    } else {
        [1.0, 0.0, 0.0, 0.0]
    };
    let largest = (1..4).fold(
        0,
        |best, i| {
            if a[i].abs() > a[best].abs() { i } else { best }
        },
    );
    if a[largest] < 0.0 {
        a = a.map(|v| -v);
    }
    (0..4)
        .filter(|&i| i != largest)
        .fold(largest as u32, |word, i| {
            (word << 10) | pack_unorm(a[i] * FRAC_1_SQRT_2 + 0.5, 10)
        })
}

/// The inverse of [`pack_rotation`]: a unit quaternion (`w, x, y, z`), the dropped component
/// recomputed as `sqrt(1 − a² − b² − c²)`.
pub fn unpack_rotation(word: u32) -> [f32; 4] {
    let part = |shift: u32| (unpack_unorm(word >> shift, 10) - 0.5) / FRAC_1_SQRT_2;
    let rest = [part(20), part(10), part(0)];
    let m = (1.0 - rest.iter().map(|v| v * v).sum::<f32>())
        .max(0.0)
        .sqrt();
    let largest = (word >> 30) as usize;
    let mut q = [0.0; 4];
    let mut others = rest.into_iter();
    for (i, slot) in q.iter_mut().enumerate() {
        *slot = if i == largest {
            m
        } else {
            others.next().unwrap_or(0.0)
        };
    }
    q
}

/// A higher SH coefficient as one byte: `trunc((v / 8 + 0.5) · 256)` clamped to [0, 255], so
/// [−4, 4) in 256 steps of 1/32.
pub fn pack_sh(v: f32) -> u8 {
    ((v / 8.0 + 0.5) * 256.0).trunc().clamp(0.0, 255.0) as u8
}

/// The inverse of [`pack_sh`]: the middle of the byte's step, except that 0 and 255 decode to
/// the ends of the range, −4 and 4.
pub fn unpack_sh(byte: u8) -> f32 {
    let n = match byte {
        0 => 0.0,
        255 => 1.0,
        b => (b as f32 + 0.5) / 256.0,
    };
    (n - 0.5) * 8.0
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// A quaternion and its negation are the same rotation: the distance between two is
    /// the smaller of `|a − b|` and `|a + b|` (largest component).
    fn rotation_distance(a: [f32; 4], b: [f32; 4]) -> f32 {
        let d = |s: f32| (0..4).map(|i| (a[i] - s * b[i]).abs()).fold(0.0, f32::max);
        d(1.0).min(d(-1.0))
    }

    #[test]
    fn ends_of_ranges_are_exact() {
        assert_eq!(
            unpack_11_10_11(pack_11_10_11([0.0, 1.0, 1.0])),
            [0.0, 1.0, 1.0]
        );
        assert_eq!(pack_11_10_11([1.0, 1.0, 1.0]), u32::MAX);
        assert_eq!(pack_8888([1.0, 0.0, 1.0, 0.0]), 0xff00_ff00);
        assert_eq!(unpack_8888(0xff00_ff00), [1.0, 0.0, 1.0, 0.0]);
        assert_eq!(
            (unpack_sh(pack_sh(-4.0)), unpack_sh(pack_sh(4.0))),
            (-4.0, 4.0)
        );
        assert_eq!(pack_sh(f32::NAN), 0);
        assert_eq!(pack_unorm(f32::NAN, 11), 0);
        // Values outside [0, 1] clamp; a range narrower than 1e-5 packs as its minimum.
        assert_eq!(pack_unorm(2.0, 10), 1023);
        assert_eq!(normalise(1.000_001, 1.0, 1.000_002), 0.0);
    }

    #[test]
    fn identity_zero_and_axis_rotations_round_trip() {
        for (q, want) in [
            ([1.0, 0.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0]),
            ([0.0, 0.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0]),
            ([0.0, 0.0, -2.0, 0.0], [0.0, 0.0, 1.0, 0.0]),
            ([0.0, 0.0, 0.0, 3.0], [0.0, 0.0, 0.0, 1.0]),
        ] {
            let back = unpack_rotation(pack_rotation(q));
            assert!(rotation_distance(back, want) < 1e-3, "{q:?}: {back:?}");
        }
        // The largest component's index sits in the top two bits.
        assert_eq!(pack_rotation([0.1, 0.2, 0.3, 0.9]) >> 30, 3);
    }

    proptest! {
        #[test]
        fn unit_values_round_trip_within_half_a_step(
            v in prop::array::uniform4(0.0f32..=1.0)
        ) {
            let p = unpack_11_10_11(pack_11_10_11([v[0], v[1], v[2]]));
            for (k, bits) in [11u32, 10, 11].into_iter().enumerate() {
                let half = 0.5 / unorm_max(bits) as f32 + 1e-6;
                prop_assert!((p[k] - v[k]).abs() <= half, "{k}: {} vs {}", p[k], v[k]);
            }
            let c = unpack_8888(pack_8888(v));
            for k in 0..4 {
                prop_assert!((c[k] - v[k]).abs() <= 0.5 / 255.0 + 1e-6);
            }
        }

        #[test]
        fn ranges_round_trip_within_half_a_step(
            min in -100.0f32..100.0, width in 1e-3f32..50.0, t in 0.0f32..=1.0
        ) {
            let max = min + width;
            let x = lerp(min, max, t);
            let back = lerp(min, max, unpack_unorm(pack_unorm(normalise(x, min, max), 11), 11));
            // Half an 11-bit step of the range, plus f32 rounding at this magnitude.
            let bound = 0.5 * width / 2047.0 + 4.0 * f32::EPSILON * min.abs().max(max.abs());
            prop_assert!((back - x).abs() <= bound, "{x} -> {back}");
        }

        #[test]
        fn rotations_round_trip_within_2_5_thousandths(
            q in prop::array::uniform4(-1.0f32..1.0)
        ) {
            let n = q.iter().map(|v| v * v).sum::<f32>().sqrt();
            prop_assume!(n > 1e-3);
            let unit = q.map(|v| v / n);
            let back = unpack_rotation(pack_rotation(q));
            let norm = back.iter().map(|v| v * v).sum::<f32>().sqrt();
            prop_assert!((norm - 1.0).abs() < 2e-3, "norm {norm}");
            // Each kept component is within half a 10-bit step of [−1/√2, 1/√2] (6.9e-4); the
            // recomputed one inherits their error, which grows as it shrinks toward 1/2.
            prop_assert!(rotation_distance(back, unit) < 2.5e-3, "{unit:?} -> {back:?}");
        }

        #[test]
        fn sh_round_trips_within_a_32nd_inside_its_range(v in -4.0f32..4.0) {
            let back = unpack_sh(pack_sh(v));
            prop_assert!((back - v).abs() <= 1.0 / 32.0 + 1e-6, "{v} -> {back}");
        }
    }
}
