//! `splat-reference`: the exact f64 reference renderer of the rasterizer's definition
//! (docs/DESIGN.md §3), written independently of `splat-raster`'s code.
//!
//! What it is: a per-pixel evaluation over every Gaussian, sorted by (camera z, index), with no
//! tiles, no extents and no bounding boxes, in f64 throughout, from raw parameters kept in f64
//! ([`Params`], so that finite differences can poke them). [`render`] also reports how close the
//! scene came to a kink of the piecewise definition, so that gradient tests can skip cases where
//! finite differences are meaningless.
//!
//! What it is not: fast, or part of any shipped binary. It is the yardstick of the rasterizer's
//! tests (`splat-raster`'s reference, gradient and parity tests, the CLI's agreement test).
#![allow(clippy::needless_range_loop)]

use glam::Mat3;
use splat_core::{Camera, Gaussians, sh_coeff_count};

/// f64 copy of the raw parameters, one flat vector per kind so finite differences can poke them.
#[derive(Clone, Debug)]
pub struct Params {
    /// SH degree of the coefficients in `sh`.
    pub degree: u32,
    /// Means, 3 per Gaussian.
    pub means: Vec<f64>,
    /// Log-scales, 3 per Gaussian.
    pub log_scales: Vec<f64>,
    /// Quaternions `w, x, y, z` (not necessarily unit), 4 per Gaussian.
    pub rotations: Vec<f64>,
    /// Opacity logits, 1 per Gaussian.
    pub logits: Vec<f64>,
    /// SH coefficients, `3 (degree + 1)²` per Gaussian, coefficient-major, channel-minor.
    pub sh: Vec<f64>,
    /// Offsets added to each projected mean (u, v) in pixels: zero, poked to check dL/d(u, v).
    pub uv_offset: Vec<f64>,
}

impl Params {
    /// The parameters of `g`, widened to f64, with zero mean offsets.
    pub fn from(g: &Gaussians) -> Self {
        let f = |v: &[f32]| v.iter().map(|&x| f64::from(x)).collect::<Vec<_>>();
        Self {
            degree: g.sh_degree,
            means: f(g.means.as_flattened()),
            log_scales: f(g.log_scales.as_flattened()),
            rotations: f(g.rotations.as_flattened()),
            logits: f(&g.opacity_logits),
            sh: f(&g.sh),
            uv_offset: vec![0.0; 2 * g.len()],
        }
    }

    /// Number of Gaussians.
    pub fn len(&self) -> usize {
        self.logits.len()
    }

    /// Whether there are no Gaussians.
    pub fn is_empty(&self) -> bool {
        self.logits.is_empty()
    }

    /// The parameter kinds by name, for finite differences: `means`, `log_scales`, `rotations`,
    /// `opacity_logits`, `sh`, `means2d` (the mean offsets).
    ///
    /// # Panics
    /// On any other name.
    pub fn kind_mut(&mut self, kind: &str) -> &mut Vec<f64> {
        match kind {
            "means" => &mut self.means,
            "log_scales" => &mut self.log_scales,
            "rotations" => &mut self.rotations,
            "opacity_logits" => &mut self.logits,
            "sh" => &mut self.sh,
            "means2d" => &mut self.uv_offset,
            _ => panic!("unknown kind {kind}"),
        }
    }
}

/// A pinhole camera in f64 (OpenCV axes, as [`Camera`]).
#[derive(Clone, Copy, Debug)]
pub struct RefCam {
    /// Image width in pixels.
    pub width: usize,
    /// Image height in pixels.
    pub height: usize,
    /// Focal length in x, pixels.
    pub fx: f64,
    /// Focal length in y, pixels.
    pub fy: f64,
    /// Principal point x, pixels.
    pub cx: f64,
    /// Principal point y, pixels.
    pub cy: f64,
    /// Row-major world-to-camera rotation.
    pub r: [[f64; 3]; 3],
    /// World-to-camera translation.
    pub t: [f64; 3],
}

impl RefCam {
    /// The camera `cam`, widened to f64.
    pub fn from(cam: &Camera) -> Self {
        let m: Mat3 = cam.rotation;
        Self {
            width: cam.width as usize,
            height: cam.height as usize,
            fx: cam.fx.into(),
            fy: cam.fy.into(),
            cx: cam.cx.into(),
            cy: cam.cy.into(),
            r: std::array::from_fn(|i| std::array::from_fn(|j| f64::from(m.col(j)[i]))),
            t: cam.translation.to_array().map(f64::from),
        }
    }

    fn apply(&self, p: [f64; 3]) -> [f64; 3] {
        std::array::from_fn(|i| (0..3).map(|j| self.r[i][j] * p[j]).sum::<f64>() + self.t[i])
    }

    fn center(&self) -> [f64; 3] {
        std::array::from_fn(|j| -(0..3).map(|i| self.r[i][j] * self.t[i]).sum::<f64>())
    }
}

/// The reference render and how close it came to a kink of the piecewise definition.
pub struct RefImage {
    /// Colour, background included, row-major.
    pub color: Vec<[f64; 3]>,
    /// Accumulated opacity `1 - T`.
    pub alpha: Vec<f64>,
    /// Un-normalised expected depth `Σ z·α·T`.
    pub depth: Vec<f64>,
    /// Per pixel: the smallest log-distance of α to 1/255 or 0.99 and of T' to 1e-4.
    pub pixel_margin: Vec<f64>,
    /// Smallest distance of any drawn Gaussian to a per-Gaussian kink (Jacobian clamp, colour
    /// clamp, near plane, opacity cull), and of any pixel (`pixel_margin`).
    pub margin: f64,
    /// Gaussians not culled.
    pub drawn: usize,
    /// Pixels whose loop stopped at `T' < 1e-4`.
    pub stopped: usize,
}

const C0: f64 = 0.282_094_791_773_878_14;
const C1: f64 = 0.488_602_511_902_919_9;
const C2: [f64; 5] = [
    1.092_548_430_592_079_2,
    -1.092_548_430_592_079_2,
    0.315_391_565_252_520_05,
    -1.092_548_430_592_079_2,
    0.546_274_215_296_039_6,
];
const C3: [f64; 7] = [
    -0.590_043_589_926_643_5,
    2.890_611_442_640_554,
    -0.457_045_799_464_465_8,
    0.373_176_332_590_115_4,
    -0.457_045_799_464_465_8,
    1.445_305_721_320_277,
    -0.590_043_589_926_643_5,
];

fn sh_basis(d: [f64; 3], degree: u32) -> Vec<f64> {
    let [x, y, z] = d;
    let (xx, yy, zz) = (x * x, y * y, z * z);
    let mut b = vec![C0];
    if degree >= 1 {
        b.extend([-C1 * y, C1 * z, -C1 * x]);
    }
    if degree >= 2 {
        b.extend([
            C2[0] * x * y,
            C2[1] * y * z,
            C2[2] * (2.0 * zz - xx - yy),
            C2[3] * x * z,
            C2[4] * (xx - yy),
        ]);
    }
    if degree >= 3 {
        b.extend([
            C3[0] * y * (3.0 * xx - yy),
            C3[1] * x * y * z,
            C3[2] * y * (4.0 * zz - xx - yy),
            C3[3] * z * (2.0 * zz - 3.0 * xx - 3.0 * yy),
            C3[4] * x * (4.0 * zz - xx - yy),
            C3[5] * z * (xx - yy),
            C3[6] * x * (xx - 3.0 * yy),
        ]);
    }
    b
}

type M3 = [[f64; 3]; 3];

fn mul(a: &M3, b: &M3) -> M3 {
    std::array::from_fn(|i| std::array::from_fn(|j| (0..3).map(|k| a[i][k] * b[k][j]).sum()))
}

fn transpose(a: &M3) -> M3 {
    std::array::from_fn(|i| std::array::from_fn(|j| a[j][i]))
}

struct Prepared {
    index: usize,
    z: f64,
    u: f64,
    v: f64,
    conic: [f64; 3],
    opacity: f64,
    rgb: [f64; 3],
}

/// Renders `p` from `cam` with DESIGN §3 in f64, per pixel over all Gaussians sorted by
/// (z, index), with SH bands up to `active` and the given background colour.
pub fn render(p: &Params, cam: &RefCam, background: [f64; 3], active: u32) -> RefImage {
    let n = p.len();
    let stride = 3 * sh_coeff_count(p.degree);
    let k_active = sh_coeff_count(active);
    let mut margin = f64::INFINITY;
    let mut list = Vec::new();
    let tan_x = 0.5 * cam.width as f64 / cam.fx;
    let tan_y = 0.5 * cam.height as f64 / cam.fy;
    let lim_x = [
        -(cam.cx / cam.fx + 0.3 * tan_x),
        (cam.width as f64 - cam.cx) / cam.fx + 0.3 * tan_x,
    ];
    let lim_y = [
        -(cam.cy / cam.fy + 0.3 * tan_y),
        (cam.height as f64 - cam.cy) / cam.fy + 0.3 * tan_y,
    ];
    let center = cam.center();
    for i in 0..n {
        let mean = [p.means[3 * i], p.means[3 * i + 1], p.means[3 * i + 2]];
        let ls = [
            p.log_scales[3 * i],
            p.log_scales[3 * i + 1],
            p.log_scales[3 * i + 2],
        ];
        let q = [
            p.rotations[4 * i],
            p.rotations[4 * i + 1],
            p.rotations[4 * i + 2],
            p.rotations[4 * i + 3],
        ];
        let sh = &p.sh[i * stride..(i + 1) * stride];
        let all = mean
            .iter()
            .chain(&ls)
            .chain(&q)
            .chain(sh)
            .chain([&p.logits[i]]);
        if all.clone().any(|v| !v.is_finite()) {
            continue;
        }
        let qn2: f64 = q.iter().map(|v| v * v).sum();
        if qn2 < 1e-12 {
            continue;
        }
        let opacity = 1.0 / (1.0 + (-p.logits[i]).exp());
        if opacity < 1.0 / 255.0 {
            continue;
        }
        let pc = cam.apply(mean);
        if pc[2] <= 0.01 {
            continue;
        }
        let qn = q.map(|v| v / qn2.sqrt());
        let [w, x, y, z] = qn;
        let rot: M3 = [
            [
                1.0 - 2.0 * (y * y + z * z),
                2.0 * (x * y - w * z),
                2.0 * (x * z + w * y),
            ],
            [
                2.0 * (x * y + w * z),
                1.0 - 2.0 * (x * x + z * z),
                2.0 * (y * z - w * x),
            ],
            [
                2.0 * (x * z - w * y),
                2.0 * (y * z + w * x),
                1.0 - 2.0 * (x * x + y * y),
            ],
        ];
        let s = ls.map(f64::exp);
        let m: M3 = std::array::from_fn(|a| std::array::from_fn(|b| rot[a][b] * s[b]));
        let sigma = mul(&m, &transpose(&m));
        let sc = mul(&mul(&cam.r, &sigma), &transpose(&cam.r));
        let zc = pc[2];
        let rx = pc[0] / zc;
        let ry = pc[1] / zc;
        let rxc = rx.clamp(lim_x[0], lim_x[1]);
        let ryc = ry.clamp(lim_y[0], lim_y[1]);
        let j = [
            [cam.fx / zc, 0.0, -cam.fx * rxc / zc],
            [0.0, cam.fy / zc, -cam.fy * ryc / zc],
        ];
        let cov = |a: usize, b: usize| -> f64 {
            (0..3)
                .map(|k| (0..3).map(|l| j[a][k] * sc[k][l] * j[b][l]).sum::<f64>())
                .sum()
        };
        let (ca, cb, cc) = (cov(0, 0) + 0.3, cov(0, 1), cov(1, 1) + 0.3);
        let det = ca * cc - cb * cb;
        if det <= 0.0 {
            continue;
        }
        let u = cam.fx * rx + cam.cx + p.uv_offset[2 * i];
        let v = cam.fy * ry + cam.cy + p.uv_offset[2 * i + 1];
        let dv: [f64; 3] = std::array::from_fn(|k| mean[k] - center[k]);
        let len = dv.iter().map(|v| v * v).sum::<f64>().sqrt();
        let basis = sh_basis(dv.map(|v| v / len), active);
        let rgb_raw: [f64; 3] = std::array::from_fn(|ch| {
            0.5 + (0..k_active)
                .map(|k| sh[3 * k + ch] * basis[k])
                .sum::<f64>()
        });
        margin = margin
            .min((rx - lim_x[0]).abs())
            .min((rx - lim_x[1]).abs())
            .min((ry - lim_y[0]).abs())
            .min((ry - lim_y[1]).abs())
            .min(zc - 0.01)
            .min((255.0 * opacity).ln().abs());
        for c in rgb_raw {
            margin = margin.min(c.abs());
        }
        list.push(Prepared {
            index: i,
            z: zc,
            u,
            v,
            conic: [cc / det, -cb / det, ca / det],
            opacity,
            rgb: rgb_raw.map(|c| c.max(0.0)),
        });
    }
    list.sort_by(|a, b| a.z.total_cmp(&b.z).then(a.index.cmp(&b.index)));
    let npix = cam.width * cam.height;
    let mut out = RefImage {
        color: vec![[0.0; 3]; npix],
        alpha: vec![0.0; npix],
        depth: vec![0.0; npix],
        pixel_margin: vec![f64::INFINITY; npix],
        margin,
        drawn: list.len(),
        stopped: 0,
    };
    for py in 0..cam.height {
        for px in 0..cam.width {
            let pix = py * cam.width + px;
            let (fx, fy) = (px as f64 + 0.5, py as f64 + 0.5);
            let mut t = 1.0;
            let mut c = [0.0; 3];
            let mut d = 0.0;
            let mut pm = f64::INFINITY;
            for g in &list {
                let dx = fx - g.u;
                let dy = fy - g.v;
                let sigma =
                    0.5 * (g.conic[0] * dx * dx + g.conic[2] * dy * dy) + g.conic[1] * dx * dy;
                if sigma < 0.0 {
                    continue;
                }
                let raw = g.opacity * (-sigma).exp();
                pm = pm
                    .min((raw / 0.99).ln().abs())
                    .min((raw * 255.0).ln().abs());
                let alpha = raw.min(0.99);
                if alpha < 1.0 / 255.0 {
                    continue;
                }
                let next = t * (1.0 - alpha);
                pm = pm.min((next / 1e-4).ln().abs());
                if next < 1e-4 {
                    out.stopped += 1;
                    break;
                }
                for ch in 0..3 {
                    c[ch] += g.rgb[ch] * alpha * t;
                }
                d += g.z * alpha * t;
                t = next;
            }
            out.color[pix] = std::array::from_fn(|ch| c[ch] + t * background[ch]);
            out.alpha[pix] = 1.0 - t;
            out.depth[pix] = d;
            out.pixel_margin[pix] = pm;
            out.margin = out.margin.min(pm);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The SH constants are the closed forms of the real SH basis (Sloan order), so the reference
    /// does not inherit a typo from a table copied elsewhere.
    #[test]
    fn sh_constants_match_closed_forms() {
        let pi = std::f64::consts::PI;
        let close = |a: f64, b: f64| (a - b).abs() <= 1e-15 * b.abs();
        assert!(close(C0, 0.5 / pi.sqrt()));
        assert!(close(C1, (3.0 / (4.0 * pi)).sqrt()));
        let c2 = [
            0.5 * (15.0 / pi).sqrt(),
            -0.5 * (15.0 / pi).sqrt(),
            0.25 * (5.0 / pi).sqrt(),
            -0.5 * (15.0 / pi).sqrt(),
            0.25 * (15.0 / pi).sqrt(),
        ];
        let c3 = [
            -0.25 * (35.0 / (2.0 * pi)).sqrt(),
            0.5 * (105.0 / pi).sqrt(),
            -0.25 * (21.0 / (2.0 * pi)).sqrt(),
            0.25 * (7.0 / pi).sqrt(),
            -0.25 * (21.0 / (2.0 * pi)).sqrt(),
            0.25 * (105.0 / pi).sqrt(),
            -0.25 * (35.0 / (2.0 * pi)).sqrt(),
        ];
        for (a, b) in C2.iter().zip(c2).chain(C3.iter().zip(c3)) {
            assert!(close(*a, b), "{a} vs {b}");
        }
    }

    /// One opaque Gaussian straight ahead: the centre pixel is its clamped SH colour at α = 0.99
    /// over the background, with depth 0.99·z.
    #[test]
    fn one_opaque_gaussian_centre_pixel() {
        let p = Params {
            degree: 0,
            means: vec![0.0, 0.0, 2.0],
            log_scales: vec![0.0; 3],
            rotations: vec![1.0, 0.0, 0.0, 0.0],
            logits: vec![20.0],
            sh: vec![1.0, 0.0, -1.0],
            uv_offset: vec![0.0; 2],
        };
        let cam = RefCam {
            width: 9,
            height: 9,
            fx: 10.0,
            fy: 10.0,
            cx: 4.5,
            cy: 4.5,
            r: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            t: [0.0; 3],
        };
        let bg = [0.25, 0.5, 0.75];
        let img = render(&p, &cam, bg, 0);
        assert_eq!(img.drawn, 1);
        let centre = img.color[4 * 9 + 4];
        let rgb = [0.5 + C0, 0.5, (0.5 - C0).max(0.0)];
        for ch in 0..3 {
            let want = 0.99 * rgb[ch] + 0.01 * bg[ch];
            assert!((centre[ch] - want).abs() < 1e-12, "{ch}: {centre:?}");
        }
        assert!((img.alpha[4 * 9 + 4] - 0.99).abs() < 1e-12);
        assert!((img.depth[4 * 9 + 4] - 0.99 * 2.0).abs() < 1e-12);
    }
}
