//! Test support: deterministic random scenes and an independent, exact per-pixel f64 reference
//! renderer of DESIGN §3 (no tiles, no extents: every Gaussian is evaluated at every pixel).
#![allow(dead_code, clippy::needless_range_loop)]

use glam::{Mat3, Vec3};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use splat_raster::{Camera, Gaussians, sh_coeff_count};

/// The identity quaternion `w, x, y, z`.
pub const Q: [f32; 4] = [1.0, 0.0, 0.0, 0.0];

/// One Gaussian with the given raw parameters and fixed, distinct SH coefficients.
pub fn one(mean: [f32; 3], log_scale: [f32; 3], q: [f32; 4], logit: f32, degree: u32) -> Gaussians {
    let k = sh_coeff_count(degree);
    Gaussians {
        sh_degree: degree,
        means: vec![mean],
        log_scales: vec![log_scale],
        rotations: vec![q],
        opacity_logits: vec![logit],
        sh: (0..3 * k).map(|i| 0.3 - 0.05 * i as f32).collect(),
    }
}

/// The Gaussians of `parts` in order, as one set (all of `parts[0]`'s SH degree).
pub fn concat(parts: &[Gaussians]) -> Gaussians {
    let mut g = Gaussians::with_degree(parts[0].sh_degree);
    for p in parts {
        g.means.extend_from_slice(&p.means);
        g.log_scales.extend_from_slice(&p.log_scales);
        g.rotations.extend_from_slice(&p.rotations);
        g.opacity_logits.extend_from_slice(&p.opacity_logits);
        g.sh.extend_from_slice(&p.sh);
    }
    g
}

/// 15 copies of the one-Gaussian set `good` (SH degree 3), each with NaN, +Inf or -Inf in one of
/// its fields: mean, log-scale, quaternion, opacity logit, SH.
pub fn poisoned_copies(good: &Gaussians) -> Vec<Gaussians> {
    let mut parts = Vec::new();
    for bad in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
        for field in 0..5 {
            let mut g = good.clone();
            match field {
                0 => g.means[0][1] = bad,
                1 => g.log_scales[0][2] = bad,
                2 => g.rotations[0][3] = bad,
                3 => g.opacity_logits[0] = bad,
                _ => g.sh[40] = bad,
            }
            parts.push(g);
        }
    }
    parts
}

/// A random camera looking at the origin from distance ~4, with fx != fy and an off-centre
/// principal point.
pub fn random_camera(rng: &mut ChaCha8Rng, width: u32, height: u32) -> Camera {
    let theta: f32 = rng.random_range(0.0..std::f32::consts::TAU);
    let phi: f32 = rng.random_range(-0.8..0.8);
    let eye = Vec3::new(theta.cos() * phi.cos(), theta.sin() * phi.cos(), phi.sin()) * 4.0;
    let mut cam = Camera::look_at(width, height, 0.9, eye, Vec3::ZERO, Vec3::Z);
    cam.fy = cam.fx * rng.random_range(0.8..1.2);
    cam.cx += rng.random_range(-0.15..0.15) * width as f32;
    cam.cy += rng.random_range(-0.15..0.15) * height as f32;
    cam
}

/// `n` random Gaussians around the origin, sized to cover a few to tens of pixels at distance 4.
pub fn random_gaussians(rng: &mut ChaCha8Rng, n: usize, degree: u32, spread: f32) -> Gaussians {
    let mut g = Gaussians::with_degree(degree);
    let k = sh_coeff_count(degree);
    for _ in 0..n {
        g.means
            .push(std::array::from_fn(|_| rng.random_range(-spread..spread)));
        g.log_scales
            .push(std::array::from_fn(|_| rng.random_range(-3.0f32..-1.2)));
        g.rotations
            .push(std::array::from_fn(|_| rng.random_range(-1.0f32..1.0)));
        g.opacity_logits.push(rng.random_range(-2.0f32..2.0));
        for c in 0..k {
            let amp = if c == 0 { 1.0 } else { 0.3 };
            for _ in 0..3 {
                g.sh.push(rng.random_range(-amp..amp));
            }
        }
    }
    g
}

pub fn rng(seed: u64) -> ChaCha8Rng {
    ChaCha8Rng::seed_from_u64(seed)
}

/// f64 copy of the raw parameters, one flat vector per kind so finite differences can poke them.
#[derive(Clone, Debug)]
pub struct Params {
    pub degree: u32,
    pub means: Vec<f64>,
    pub log_scales: Vec<f64>,
    pub rotations: Vec<f64>,
    pub logits: Vec<f64>,
    pub sh: Vec<f64>,
    /// Offsets added to each projected mean (u, v) in pixels: zero, poked to check dL/d(u, v).
    pub uv_offset: Vec<f64>,
}

impl Params {
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

    pub fn len(&self) -> usize {
        self.logits.len()
    }

    /// The parameter kinds by name, for finite differences.
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

/// f64 camera.
#[derive(Clone, Copy, Debug)]
pub struct RefCam {
    pub width: usize,
    pub height: usize,
    pub fx: f64,
    pub fy: f64,
    pub cx: f64,
    pub cy: f64,
    /// Row-major world-to-camera rotation.
    pub r: [[f64; 3]; 3],
    pub t: [f64; 3],
}

impl RefCam {
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
    pub color: Vec<[f64; 3]>,
    pub alpha: Vec<f64>,
    pub depth: Vec<f64>,
    /// Per pixel: the smallest log-distance of α to 1/255 or 0.99 and of T' to 1e-4.
    pub pixel_margin: Vec<f64>,
    /// Smallest distance of any drawn Gaussian to a per-Gaussian kink (Jacobian clamp, colour
    /// clamp, near plane, opacity cull), and of any pixel (`pixel_margin`).
    pub margin: f64,
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

/// Renders with DESIGN §3 in f64, per pixel over all Gaussians sorted by (z, index).
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
