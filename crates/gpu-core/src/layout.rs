//! The Rust mirrors of the WGSL structs a kernel uploads, checked against the shaders.
//!
//! Every `#[repr(C)]` struct uploaded as a uniform (the sort's `Params`, the scan's `ScanParams`
//! here; the rasterizer's `Frame` in `splat-raster`) is declared through [`wgsl_mirror!`], which
//! records each field's name, type, byte offset and size; a test of the crate that declares it
//! reads the WGSL declaration from the shader source ([`crate::wgsl_text::check_mirror`]) and
//! fails when the two differ in any of them, or in the struct's size.
//!
//! What it is not: a generator. The WGSL stays hand-written; the test keeps the two in step.

/// Declares a struct that mirrors a WGSL struct field for field (same names, scalar types `f32`,
/// `u32`, `i32`), as written, plus `FIELDS`: `(name, type, byte offset, byte size)` of each
/// field in order, for the layout test (compiled for the declaring crate's tests only).
#[macro_export]
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
