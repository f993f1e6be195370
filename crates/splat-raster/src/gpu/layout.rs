//! The Rust mirrors of the WGSL structs the backend uploads, checked against the shaders.
//!
//! Every `#[repr(C)]` struct that is uploaded as a uniform ([`FrameUniform`](super::frame::FrameUniform)
//! as `Frame`, the sort's `Params`, the scan's `ScanParams`) is declared through
//! [`wgsl_mirror!`], which records each field's name, type, byte offset and size; a test below
//! reads the WGSL declaration from the shader source and fails when the two differ in any of
//! them, or in the struct's size. The record layouts that exist only on the device are checked
//! by size (`Splat`) and stride (the backward's output) against the constants the Rust side
//! sizes buffers with.
//!
//! What it is not: a generator. The WGSL stays hand-written; the test keeps the two in step.

/// Declares a struct that mirrors a WGSL struct field for field (same names, scalar types `f32`,
/// `u32`, `i32`), as written, plus `FIELDS`: `(name, type, byte offset, byte size)` of each
/// field in order, for the layout test (compiled for tests only).
macro_rules! wgsl_mirror {
    (
        $(#[$meta:meta])*
        $vis:vis struct $name:ident {
            $( $(#[$fmeta:meta])* $fvis:vis $field:ident : $ty:ty ),* $(,)?
        }
    ) => {
        $(#[$meta])*
        $vis struct $name {
            $( $(#[$fmeta])* $fvis $field: $ty ),*
        }

        #[cfg(test)]
        impl $name {
            /// `(name, type, byte offset, byte size)` of every field, in declaration order.
            pub(crate) const FIELDS: &'static [(&'static str, &'static str, usize, usize)] = &[
                $((
                    stringify!($field),
                    stringify!($ty),
                    ::std::mem::offset_of!($name, $field),
                    ::std::mem::size_of::<$ty>(),
                )),*
            ];
        }
    };
}

pub(crate) use wgsl_mirror;

#[cfg(test)]
mod tests {
    use super::super::backward::OUT_STRIDE;
    use super::super::forward::SPLAT_BYTES;
    use super::super::frame::FrameUniform;
    use super::super::scan::ScanParams;
    use super::super::sort::Params;
    use crate::wgsl_text::{const_value, struct_layout};

    const COMMON: &str = include_str!("shaders/common.wgsl");
    const SORT_COMMON: &str = include_str!("shaders/sort_common.wgsl");
    const SCAN: &str = include_str!("shaders/scan.wgsl");
    const PROJECT_BWD: &str = include_str!("shaders/project_bwd.wgsl");

    type Fields = &'static [(&'static str, &'static str, usize, usize)];

    /// Panics, naming the struct and the first difference, unless the Rust fields and size equal
    /// the WGSL declaration's.
    fn check(fields: Fields, rust_size: usize, src: &str, wgsl_name: &str) {
        let (members, wgsl_size) = struct_layout(src, wgsl_name);
        let wgsl: Vec<(&str, &str, usize, usize)> = members
            .iter()
            .map(|m| (m.name.as_str(), m.ty.as_str(), m.offset, m.size))
            .collect();
        for (k, (r, w)) in fields.iter().zip(&wgsl).enumerate() {
            assert_eq!(
                r, w,
                "{wgsl_name} field {k}: Rust (name, type, offset, size) vs WGSL"
            );
        }
        assert_eq!(fields.len(), wgsl.len(), "{wgsl_name}: number of fields");
        assert_eq!(rust_size, wgsl_size, "{wgsl_name}: size in bytes");
    }

    #[test]
    fn uniforms_match_their_wgsl_structs() {
        check(
            FrameUniform::FIELDS,
            size_of::<FrameUniform>(),
            COMMON,
            "Frame",
        );
        check(Params::FIELDS, size_of::<Params>(), SORT_COMMON, "Params");
        check(
            ScanParams::FIELDS,
            size_of::<ScanParams>(),
            SCAN,
            "ScanParams",
        );
    }

    #[test]
    fn device_records_match_the_sizes_the_buffers_are_made_for() {
        assert_eq!(struct_layout(COMMON, "Splat").1 as u64, SPLAT_BYTES);
        assert_eq!(const_value(PROJECT_BWD, "OUT_STRIDE"), OUT_STRIDE as f64);
    }

    #[test]
    fn dispatch_sizes_and_cull_codes_match_the_kernels() {
        use super::super::forward::cull;
        // The Rust side sizes the dispatches and buffers with these; the kernels index with theirs.
        assert_eq!(
            const_value(SCAN, "BLOCK"),
            f64::from(super::super::scan::BLOCK)
        );
        assert_eq!(
            const_value(SORT_COMMON, "BLOCK"),
            f64::from(super::super::sort::BLOCK)
        );
        assert_eq!(
            const_value(SORT_COMMON, "BINS"),
            f64::from(super::super::sort::BINS)
        );
        // The projection counts each Gaussian at the index of its `CULL_*` code.
        for (name, index) in [
            ("CULL_NON_FINITE", cull::NON_FINITE),
            ("CULL_ZERO_QUATERNION", cull::ZERO_QUATERNION),
            ("CULL_LOW_OPACITY", cull::LOW_OPACITY),
            ("CULL_BEHIND_NEAR_PLANE", cull::BEHIND_NEAR_PLANE),
            ("CULL_DEGENERATE", cull::DEGENERATE),
            ("CULL_OFF_SCREEN", cull::OFF_SCREEN),
        ] {
            assert_eq!(const_value(COMMON, name), index as f64, "{name}");
        }
        assert_eq!(cull::DRAWN, 0, "a Gaussian with reason 0 is drawn");
    }

    #[test]
    fn a_drifted_declaration_is_caught() {
        // Two fields swapped, a type changed, a field dropped: each must fail the check.
        let swapped = SCAN.replace(
            "    pad0: u32,\n    pad1: u32,",
            "    pad1: u32,\n    pad0: u32,",
        );
        let retyped = SORT_COMMON.replace("    shift: u32,", "    shift: f32,");
        let dropped = SCAN.replace("    pad2: u32,\n", "");
        assert_ne!(swapped, SCAN);
        assert_ne!(retyped, SORT_COMMON);
        assert_ne!(dropped, SCAN);
        let scan = |src: String| {
            std::panic::catch_unwind(move || {
                check(
                    ScanParams::FIELDS,
                    size_of::<ScanParams>(),
                    &src,
                    "ScanParams",
                );
            })
        };
        assert!(scan(swapped).is_err());
        assert!(scan(dropped).is_err());
        let sort = std::panic::catch_unwind(move || {
            check(Params::FIELDS, size_of::<Params>(), &retyped, "Params");
        });
        assert!(sort.is_err());
    }
}
