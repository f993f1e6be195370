//! Real spherical harmonics up to degree 3 in the Sloan basis order with the constants of the
//! 3DGS reference implementation, and the basis gradient with respect to the view direction.

pub use splat_core::sh::{SH_C0, SH_C1, SH_C2, SH_C3};

/// The basis values for the unit direction `d` at `degree` (entries past `(degree+1)²` are 0).
pub fn basis(d: [f32; 3], degree: u32) -> [f32; 16] {
    basis_and_grad(d, degree).0
}

/// The basis values and their gradients with respect to the (unit) direction components.
pub fn basis_and_grad(d: [f32; 3], degree: u32) -> ([f32; 16], [[f32; 3]; 16]) {
    let [x, y, z] = d;
    let mut b = [0.0f32; 16];
    let mut g = [[0.0f32; 3]; 16];
    b[0] = SH_C0;
    if degree >= 1 {
        b[1] = -SH_C1 * y;
        g[1] = [0.0, -SH_C1, 0.0];
        b[2] = SH_C1 * z;
        g[2] = [0.0, 0.0, SH_C1];
        b[3] = -SH_C1 * x;
        g[3] = [-SH_C1, 0.0, 0.0];
    }
    if degree >= 2 {
        let (xx, yy, zz) = (x * x, y * y, z * z);
        let c = SH_C2;
        b[4] = c[0] * x * y;
        g[4] = [c[0] * y, c[0] * x, 0.0];
        b[5] = c[1] * y * z;
        g[5] = [0.0, c[1] * z, c[1] * y];
        b[6] = c[2] * (2.0 * zz - xx - yy);
        g[6] = [-2.0 * c[2] * x, -2.0 * c[2] * y, 4.0 * c[2] * z];
        b[7] = c[3] * x * z;
        g[7] = [c[3] * z, 0.0, c[3] * x];
        b[8] = c[4] * (xx - yy);
        g[8] = [2.0 * c[4] * x, -2.0 * c[4] * y, 0.0];
    }
    if degree >= 3 {
        let (xx, yy, zz) = (x * x, y * y, z * z);
        let c = SH_C3;
        b[9] = c[0] * y * (3.0 * xx - yy);
        g[9] = [c[0] * 6.0 * x * y, c[0] * (3.0 * xx - 3.0 * yy), 0.0];
        b[10] = c[1] * x * y * z;
        g[10] = [c[1] * y * z, c[1] * x * z, c[1] * x * y];
        b[11] = c[2] * y * (4.0 * zz - xx - yy);
        g[11] = [
            c[2] * (-2.0 * x * y),
            c[2] * (4.0 * zz - xx - 3.0 * yy),
            c[2] * 8.0 * y * z,
        ];
        b[12] = c[3] * z * (2.0 * zz - 3.0 * xx - 3.0 * yy);
        g[12] = [
            c[3] * (-6.0 * x * z),
            c[3] * (-6.0 * y * z),
            c[3] * (6.0 * zz - 3.0 * xx - 3.0 * yy),
        ];
        b[13] = c[4] * x * (4.0 * zz - xx - yy);
        g[13] = [
            c[4] * (4.0 * zz - 3.0 * xx - yy),
            c[4] * (-2.0 * x * y),
            c[4] * 8.0 * x * z,
        ];
        b[14] = c[5] * z * (xx - yy);
        g[14] = [c[5] * 2.0 * x * z, c[5] * (-2.0 * y * z), c[5] * (xx - yy)];
        b[15] = c[6] * x * (xx - 3.0 * yy);
        g[15] = [c[6] * (3.0 * xx - 3.0 * yy), c[6] * (-6.0 * x * y), 0.0];
    }
    (b, g)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn basis_gradient_matches_central_differences() {
        let d = [0.3f32, -0.5, 0.81];
        let (_, g) = basis_and_grad(d, 3);
        let h = 1e-3f32;
        for axis in 0..3 {
            let mut p = d;
            let mut m = d;
            p[axis] += h;
            m[axis] -= h;
            let (bp, bm) = (basis(p, 3), basis(m, 3));
            for k in 0..16 {
                let fd = (bp[k] - bm[k]) / (2.0 * h);
                assert!(
                    (fd - g[k][axis]).abs() < 2e-3,
                    "k={k} axis={axis}: {fd} vs {}",
                    g[k][axis]
                );
            }
        }
    }

    #[test]
    fn lower_degrees_leave_higher_bands_zero() {
        let b = basis([0.0, 0.6, 0.8], 1);
        assert!(b[4..].iter().all(|&v| v == 0.0));
        assert!((b[2] - SH_C1 * 0.8).abs() < 1e-7);
    }
}
