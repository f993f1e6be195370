//! Per-Gaussian work of DESIGN §3: activation, culling, covariance projection with the clamped
//! Jacobian and 0.3 dilation, conic, opacity-aware screen extent, SH colour; and its backward pass.

use glam::{DMat3, DVec3, Vec3};
use splat_core::sigmoid;

use crate::constants::{ALPHA_MIN, DILATION, MAX_COLOR, NEAR_PLANE, QUAT_NORM2_MIN, TILE};
use crate::frame::Frame;
use crate::gaussians::GaussiansView;
use crate::sh;

/// Why one Gaussian was not drawn.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum CullReason {
    NonFinite,
    ZeroQuaternion,
    LowOpacity,
    BehindNearPlane,
    DegenerateCovariance,
    OffScreen,
}

/// What compositing needs of one drawn Gaussian (the hot loop's record).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct Splat {
    /// Projected mean in pixels.
    pub u: f32,
    pub v: f32,
    /// Conic (a, b, c) = inverse of Σ2d: `σ = 0.5 (a dx² + c dy²) + b dx dy`.
    pub a: f32,
    pub b: f32,
    pub c: f32,
    pub opacity: f32,
    /// Pixels with `σ > sigma_cut` cannot reach `α >= 1/255` (a safe pre-filter, see `alpha_at`).
    pub sigma_cut: f32,
    pub rgb: [f32; 3],
    /// Camera-space depth.
    pub z: f32,
    /// Inclusive pixel bounding box `[x_lo, y_lo, x_hi, y_hi]` of the opacity-aware extent,
    /// clipped to the image: pixels outside it cannot reach `α >= 1/255`.
    pub bbox: [u32; 4],
}

impl Splat {
    /// `σ` at offset `(dx, dy)` from the projected mean.
    fn sigma_at(&self, dx: f32, dy: f32) -> f32 {
        0.5 * (self.a * dx * dx + self.c * dy * dy) + self.b * dx * dy
    }

    /// Smallest `σ` over the continuous rectangle `[x0, x1] × [y0, y1]` (pixel coordinates).
    /// `σ` is a convex quadratic with its minimum 0 at the mean, so when the mean lies outside
    /// the rectangle the minimum lies on one of its edges, where it is a 1-D clamped minimum.
    pub fn min_sigma_over(&self, x0: f32, x1: f32, y0: f32, y1: f32) -> f32 {
        let (dx0, dx1, dy0, dy1) = (x0 - self.u, x1 - self.u, y0 - self.v, y1 - self.v);
        self.min_sigma_at(
            [dx0, dx1],
            [dy0, dy1],
            self.edge_minima_y([dx0, dx1]),
            self.edge_minima_x([dy0, dy1]),
        )
    }

    /// On the vertical edges `dx`, the unclamped `dy` of the 1-D minima: `−b·dx / c`.
    fn edge_minima_y(&self, dx: [f32; 2]) -> [f32; 2] {
        dx.map(|dx| -self.b * dx / self.c)
    }

    /// On the horizontal edges `dy`, the unclamped `dx` of the 1-D minima: `−b·dy / a`.
    fn edge_minima_x(&self, dy: [f32; 2]) -> [f32; 2] {
        dy.map(|dy| -self.b * dy / self.a)
    }

    /// [`Splat::min_sigma_over`] of the rectangle with offsets `dx`, `dy` from the mean, given
    /// its edges' unclamped minima ([`Splat::edge_minima_y`], [`Splat::edge_minima_x`]).
    fn min_sigma_at(&self, dx: [f32; 2], dy: [f32; 2], at_y: [f32; 2], at_x: [f32; 2]) -> f32 {
        if dx[0] <= 0.0 && dx[1] >= 0.0 && dy[0] <= 0.0 && dy[1] >= 0.0 {
            return 0.0;
        }
        let mut best = f32::INFINITY;
        for (dx, at) in dx.into_iter().zip(at_y) {
            best = best.min(self.sigma_at(dx, at.clamp(dy[0], dy[1])));
        }
        for (dy, at) in dy.into_iter().zip(at_x) {
            best = best.min(self.sigma_at(at.clamp(dx[0], dx[1]), dy));
        }
        best
    }

    /// The cut-off [`Splat::touches_tile`] compares the smallest `σ` with: `sigma_cut` with a
    /// small slack for rounding, so no pixel that the per-pixel test keeps is lost.
    fn tile_cut(&self) -> f32 {
        self.sigma_cut * (1.0 + 1e-4) + 1e-4
    }

    /// Whether some pixel centre of tile `(tx, ty)` inside the image may reach `σ <= sigma_cut`
    /// (with a small slack for rounding, so no pixel that the per-pixel test keeps is lost).
    pub fn touches_tile(&self, frame: &Frame, tx: u32, ty: u32) -> bool {
        let [x0, x1] = pixel_span(tx, frame.width);
        let [y0, y1] = pixel_span(ty, frame.height);
        let m = self.min_sigma_over(x0, x1, y0, y1);
        // NaN (degenerate arithmetic) keeps the tile: the per-pixel test decides.
        let beyond = m > self.tile_cut();
        !beyond
    }

    /// [`Splat::touches_tile`] over the inclusive tile rectangle `[tx0, ty0, tx1, ty1]`:
    /// `touched(tx, ty)` for each tile it keeps, in ascending tile order (row by row). The same
    /// decisions bit for bit (the same operations on the same values), with the divisions that
    /// depend only on a tile's column or row done once per column (up to [`HOISTED_COLUMNS`]
    /// columns) or row instead of once per tile.
    pub fn for_each_touched_tile(
        &self,
        frame: &Frame,
        [tx0, ty0, tx1, ty1]: [u32; 4],
        mut touched: impl FnMut(u32, u32),
    ) {
        let columns = (tx1 - tx0 + 1) as usize;
        if columns > HOISTED_COLUMNS {
            for ty in ty0..=ty1 {
                for tx in tx0..=tx1 {
                    if self.touches_tile(frame, tx, ty) {
                        touched(tx, ty);
                    }
                }
            }
            return;
        }
        let mut dx = [[0f32; 2]; HOISTED_COLUMNS];
        let mut at_y = [[0f32; 2]; HOISTED_COLUMNS];
        for (k, tx) in (tx0..=tx1).enumerate() {
            dx[k] = pixel_span(tx, frame.width).map(|x| x - self.u);
            at_y[k] = self.edge_minima_y(dx[k]);
        }
        let cut = self.tile_cut();
        for ty in ty0..=ty1 {
            let dy = pixel_span(ty, frame.height).map(|y| y - self.v);
            let at_x = self.edge_minima_x(dy);
            for (k, tx) in (tx0..=tx1).enumerate() {
                let m = self.min_sigma_at(dx[k], dy, at_y[k], at_x);
                // NaN keeps the tile, as in `touches_tile`.
                let beyond = m > cut;
                if !beyond {
                    touched(tx, ty);
                }
            }
        }
    }
}

/// Tile columns of a rectangle whose per-column divisions
/// [`Splat::for_each_touched_tile`] keeps on the stack (wider rectangles divide per tile).
pub(crate) const HOISTED_COLUMNS: usize = 64;

/// The first and last pixel centres `[p0 + 0.5, p1 + 0.5]` of tile row or column `t` in an image
/// `size` pixels across (the last tile may be partial).
fn pixel_span(t: u32, size: u32) -> [f32; 2] {
    let p0 = t * TILE;
    let p1 = (p0 + TILE - 1).min(size - 1);
    [p0 as f32 + 0.5, p1 as f32 + 0.5]
}

/// A drawn Gaussian: its record, its tile rectangle (inclusive) and its 3σ screen radius.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Projected {
    pub splat: Splat,
    pub tiles: [u32; 4],
    pub radius: f32,
}

/// Raw parameters of Gaussian `i`, and whether they are all finite.
struct Raw<'a> {
    mean: Vec3,
    log_scale: Vec3,
    q: [f32; 4],
    logit: f32,
    sh: &'a [f32],
}

fn raw<'a>(g: &GaussiansView<'a>, i: usize) -> Raw<'a> {
    let stride = g.sh_stride();
    Raw {
        mean: Vec3::from_array(g.means[i]),
        log_scale: Vec3::from_array(g.log_scales[i]),
        q: g.rotations[i],
        logit: g.opacity_logits[i],
        sh: &g.sh[i * stride..(i + 1) * stride],
    }
}

impl Raw<'_> {
    fn all_finite(&self) -> bool {
        self.mean.is_finite()
            && self.log_scale.is_finite()
            && self.q.iter().all(|v| v.is_finite())
            && self.logit.is_finite()
            && self.sh.iter().all(|v| v.is_finite())
    }
}

/// Rotation matrix of a unit quaternion `w, x, y, z`.
fn rotation(q: [f64; 4]) -> DMat3 {
    let [w, x, y, z] = q;
    DMat3::from_cols(
        DVec3::new(
            1.0 - 2.0 * (y * y + z * z),
            2.0 * (x * y + w * z),
            2.0 * (x * z - w * y),
        ),
        DVec3::new(
            2.0 * (x * y - w * z),
            1.0 - 2.0 * (x * x + z * z),
            2.0 * (y * z + w * x),
        ),
        DVec3::new(
            2.0 * (x * z + w * y),
            2.0 * (y * z - w * x),
            1.0 - 2.0 * (x * x + y * y),
        ),
    )
}

/// Intermediate values of one Gaussian's projection, shared by forward and backward.
struct Geometry {
    qn: [f64; 4],
    q_norm: f64,
    rot: DMat3,
    scale: DVec3,
    /// `M = R S`.
    m: DMat3,
    /// Camera-space covariance `W Σ Wᵀ`.
    sigma_cam: DMat3,
    p: DVec3,
    /// Jacobian rows.
    j0: DVec3,
    j1: DVec3,
    /// Clamped x/z and y/z used in the Jacobian, and whether the clamp was active.
    rxc: f64,
    ryc: f64,
    clamped_x: bool,
    clamped_y: bool,
    /// Σ2d entries (A, B, C).
    cov2d: [f64; 3],
    det: f64,
    opacity: f32,
}

fn geometry(frame: &Frame, r: &Raw<'_>) -> Result<Geometry, CullReason> {
    if !r.all_finite() {
        return Err(CullReason::NonFinite);
    }
    let q = r.q.map(f64::from);
    let n2 = q.iter().map(|v| v * v).sum::<f64>();
    if n2 < f64::from(QUAT_NORM2_MIN) {
        return Err(CullReason::ZeroQuaternion);
    }
    let opacity = sigmoid(r.logit);
    if opacity < ALPHA_MIN {
        return Err(CullReason::LowOpacity);
    }
    let p = frame.w * r.mean.as_dvec3() + frame.t;
    if !p.is_finite() {
        return Err(CullReason::OffScreen);
    }
    if p.z <= f64::from(NEAR_PLANE) {
        return Err(CullReason::BehindNearPlane);
    }
    let q_norm = n2.sqrt();
    let qn = q.map(|v| v / q_norm);
    let rot = rotation(qn);
    let scale = r.log_scale.as_dvec3().exp();
    let m = rot * DMat3::from_diagonal(scale);
    let sigma = m * m.transpose();
    let sigma_cam = frame.w * sigma * frame.w.transpose();
    let z = p.z;
    let rx = p.x / z;
    let ry = p.y / z;
    let rxc = rx.clamp(frame.lim_x[0], frame.lim_x[1]);
    let ryc = ry.clamp(frame.lim_y[0], frame.lim_y[1]);
    let j0 = DVec3::new(frame.fx / z, 0.0, -frame.fx * rxc / z);
    let j1 = DVec3::new(0.0, frame.fy / z, -frame.fy * ryc / z);
    let s0 = sigma_cam * j0;
    let s1 = sigma_cam * j1;
    let dilation = f64::from(DILATION);
    let cov2d = [j0.dot(s0) + dilation, j0.dot(s1), j1.dot(s1) + dilation];
    let det = cov2d[0] * cov2d[2] - cov2d[1] * cov2d[1];
    if !det.is_finite() || det <= 0.0 || !cov2d.iter().all(|v| v.is_finite()) {
        return Err(CullReason::DegenerateCovariance);
    }
    Ok(Geometry {
        qn,
        q_norm,
        rot,
        scale,
        m,
        sigma_cam,
        p,
        j0,
        j1,
        rxc,
        ryc,
        clamped_x: rx != rxc,
        clamped_y: ry != ryc,
        cov2d,
        det,
        opacity,
    })
}

/// Forward work of Gaussian `i`: its compositing record, tile rectangle and screen radius.
pub(crate) fn project(
    frame: &Frame,
    g: &GaussiansView<'_>,
    active_degree: u32,
    i: usize,
) -> Result<Projected, CullReason> {
    let r = raw(g, i);
    let geo = geometry(frame, &r)?;
    let p = geo.p;
    let u_f64 = frame.fx * p.x / p.z + frame.cx;
    let v_f64 = frame.fy * p.y / p.z + frame.cy;
    let [ca, cb, cc] = geo.cov2d;
    let det = geo.det;
    let (u, v, z) = (u_f64 as f32, v_f64 as f32, p.z as f32);
    let (a, b, c) = ((cc / det) as f32, (-cb / det) as f32, (ca / det) as f32);
    if ![u, v, z].iter().all(|x| x.is_finite()) {
        return Err(CullReason::OffScreen);
    }
    if ![a, b, c].iter().all(|x| x.is_finite()) {
        return Err(CullReason::DegenerateCovariance);
    }
    // α >= 1/255 needs o·exp(-σ) >= 1/255, i.e. σ <= ln(255 o). The ellipse dᵀ Σ2d⁻¹ d <= 2 s
    // spans ±sqrt(2 s Σ2d_xx) in x and ±sqrt(2 s Σ2d_yy) in y. A relative margin and a small
    // absolute one keep the bound safe under f32 rounding of σ and exp.
    let s_max = (255.0 * geo.opacity).ln().max(0.0);
    let sigma_cut = s_max * 1.001 + 1e-3;
    let ext_x = (2.0 * f64::from(sigma_cut) * ca).sqrt() + 1e-2;
    let ext_y = (2.0 * f64::from(sigma_cut) * cc).sqrt() + 1e-2;
    // Pixels i whose centre i + 0.5 lies within [u - ext, u + ext].
    let (u_px, v_px) = (f64::from(u), f64::from(v));
    let x_lo = (u_px - ext_x - 0.5).ceil().max(0.0);
    let x_hi = (u_px + ext_x - 0.5)
        .floor()
        .min(f64::from(frame.width) - 1.0);
    let y_lo = (v_px - ext_y - 0.5).ceil().max(0.0);
    let y_hi = (v_px + ext_y - 0.5)
        .floor()
        .min(f64::from(frame.height) - 1.0);
    if !(x_lo <= x_hi && y_lo <= y_hi) {
        return Err(CullReason::OffScreen);
    }
    let tiles = [
        x_lo as u32 / TILE,
        y_lo as u32 / TILE,
        x_hi as u32 / TILE,
        y_hi as u32 / TILE,
    ];
    let mid = 0.5 * (ca + cc);
    let lambda_max = mid + (mid * mid - det).max(0.0).sqrt();
    let radius = (3.0 * lambda_max.sqrt()) as f32;
    let rgb = color(frame, r.mean, r.sh, active_degree).0;
    if !rgb.iter().all(|c| c.is_finite() && *c <= MAX_COLOR) {
        return Err(CullReason::NonFinite);
    }
    let splat = Splat {
        u,
        v,
        a,
        b,
        c,
        opacity: geo.opacity,
        sigma_cut,
        rgb,
        z,
        bbox: [x_lo as u32, y_lo as u32, x_hi as u32, y_hi as u32],
    };
    // Whether any tile is touched does not depend on the order the tiles are tried in: the
    // tile of the mean first (touched unless the Gaussian is all but invisible), then the rest.
    let [mx, my] = [u, v].map(|p| (p / TILE as f32) as u32);
    let mean_in_rect = (tiles[0]..=tiles[2]).contains(&mx) && (tiles[1]..=tiles[3]).contains(&my);
    let touches_any = (mean_in_rect && splat.touches_tile(frame, mx, my))
        || (tiles[1]..=tiles[3])
            .any(|ty| (tiles[0]..=tiles[2]).any(|tx| splat.touches_tile(frame, tx, ty)));
    if !touches_any {
        return Err(CullReason::OffScreen);
    }
    Ok(Projected {
        splat,
        tiles,
        radius: if radius.is_finite() { radius } else { f32::MAX },
    })
}

/// SH colour `max(sh·basis(normalize(mean - C)) + 0.5, 0)`; also returns the unclamped value.
fn color(frame: &Frame, mean: Vec3, sh: &[f32], degree: u32) -> ([f32; 3], [f32; 3]) {
    let dir = (mean - frame.center).normalize();
    let basis = sh::basis(dir.to_array(), degree);
    let count = crate::gaussians::sh_coeff_count(degree);
    let mut raw = [0.5f32; 3];
    for (ch, out) in raw.iter_mut().enumerate() {
        let mut s = 0.0f32;
        for (k, bk) in basis.iter().enumerate().take(count) {
            s += sh[k * 3 + ch] * bk;
        }
        *out += s;
    }
    (raw.map(|v| v.max(0.0)), raw)
}

/// Loss gradients with respect to one Gaussian's compositing record.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct SplatGrads {
    pub u: f32,
    pub v: f32,
    pub a: f32,
    pub b: f32,
    pub c: f32,
    pub opacity: f32,
    pub rgb: [f32; 3],
    pub z: f32,
}

impl SplatGrads {
    pub fn add(&mut self, o: &SplatGrads) {
        self.u += o.u;
        self.v += o.v;
        self.a += o.a;
        self.b += o.b;
        self.c += o.c;
        self.opacity += o.opacity;
        for ch in 0..3 {
            self.rgb[ch] += o.rgb[ch];
        }
        self.z += o.z;
    }
}

/// Gradients of one Gaussian's raw parameters.
#[derive(Clone, Debug, Default, PartialEq)]
pub(crate) struct RawGrads {
    pub mean: [f32; 3],
    pub log_scale: [f32; 3],
    pub q: [f32; 4],
    pub logit: f32,
}

fn at(m: &DMat3, i: usize, j: usize) -> f64 {
    m.col(j)[i]
}

fn outer(a: DVec3, b: DVec3) -> DMat3 {
    DMat3::from_cols(a * b.x, a * b.y, a * b.z)
}

/// Backward of [`project`]: chains the record's gradient to the raw parameters of Gaussian `i`.
/// SH gradients are written to `sh_grad` (`sh_stride` floats, zero outside the active bands).
/// Returns `None` for a culled Gaussian (its gradient is zero and `sh_grad` is left untouched).
pub(crate) fn project_backward_into(
    frame: &Frame,
    g: &GaussiansView<'_>,
    active_degree: u32,
    i: usize,
    d: &SplatGrads,
    sh_grad: &mut [f32],
) -> Option<RawGrads> {
    let r = raw(g, i);
    let geo = geometry(frame, &r).ok()?;
    let (fx, fy) = (frame.fx, frame.fy);
    let p = geo.p;
    let z = p.z;
    let (du, dv) = (f64::from(d.u), f64::from(d.v));
    let mut dp = DVec3::new(0.0, 0.0, f64::from(d.z));

    // Projected mean u = fx x/z + cx, v = fy y/z + cy.
    dp.x += du * fx / z;
    dp.y += dv * fy / z;
    dp.z += -du * fx * p.x / (z * z) - dv * fy * p.y / (z * z);

    // Conic Q = Σ2d⁻¹: G_Σ2d = -Q G_Q Q with G_Q = [[ga, gb/2], [gb/2, gc]].
    let [ca, cb, cc] = geo.cov2d;
    let det = geo.det;
    let (qa, qb, qc) = (cc / det, -cb / det, ca / det);
    let (ga, gb, gc) = (f64::from(d.a), 0.5 * f64::from(d.b), f64::from(d.c));
    // X = G_Q Q
    let x00 = ga * qa + gb * qb;
    let x01 = ga * qb + gb * qc;
    let x10 = gb * qa + gc * qb;
    let x11 = gb * qb + gc * qc;
    // G = -Q X (symmetric)
    let g00 = -(qa * x00 + qb * x10);
    let g01 = -(qa * x01 + qb * x11);
    let g11 = -(qb * x01 + qc * x11);

    // Σ2d_ab = j_a · S j_b.
    let sc = geo.sigma_cam;
    let (j0, j1) = (geo.j0, geo.j1);
    let g_sc = outer(j0, j0) * g00 + (outer(j0, j1) + outer(j1, j0)) * g01 + outer(j1, j1) * g11;
    let gj0 = (sc * j0 * g00 + sc * j1 * g01) * 2.0;
    let gj1 = (sc * j0 * g01 + sc * j1 * g11) * 2.0;
    // J rows: j0 = (fx/z, 0, -fx r_x / z), r_x = clamp(x/z); same for y.
    dp.z += -gj0.x * fx / (z * z) - gj1.y * fy / (z * z);
    let (rxc, ryc) = (geo.rxc, geo.ryc);
    if geo.clamped_x {
        dp.z += gj0.z * fx * rxc / (z * z);
    } else {
        dp.x += -gj0.z * fx / (z * z);
        dp.z += gj0.z * 2.0 * fx * p.x / (z * z * z);
    }
    if geo.clamped_y {
        dp.z += gj1.z * fy * ryc / (z * z);
    } else {
        dp.y += -gj1.z * fy / (z * z);
        dp.z += gj1.z * 2.0 * fy * p.y / (z * z * z);
    }
    let d_mean64 = frame.w.transpose() * dp;

    // Σ_cam = W Σ Wᵀ, Σ = M Mᵀ, M = R S.
    let g_sigma = frame.w.transpose() * g_sc * frame.w;
    let g_m = g_sigma * geo.m * 2.0;
    let mut g_scale = [0.0f64; 3];
    let mut g_rot = DMat3::ZERO;
    for (j, gs) in g_scale.iter_mut().enumerate() {
        let col = g_m.col(j);
        *gs = col.dot(geo.rot.col(j));
        *g_rot.col_mut(j) = col * geo.scale[j];
    }
    let log_scale = [
        (g_scale[0] * geo.scale.x) as f32,
        (g_scale[1] * geo.scale.y) as f32,
        (g_scale[2] * geo.scale.z) as f32,
    ];
    let [w, x, y, zq] = geo.qn;
    let gr = |i, j| at(&g_rot, i, j);
    let dqn = [
        2.0 * (-zq * gr(0, 1) + y * gr(0, 2) + zq * gr(1, 0) - x * gr(1, 2) - y * gr(2, 0)
            + x * gr(2, 1)),
        2.0 * (y * gr(0, 1) + zq * gr(0, 2) + y * gr(1, 0) - 2.0 * x * gr(1, 1) - w * gr(1, 2)
            + zq * gr(2, 0)
            + w * gr(2, 1)
            - 2.0 * x * gr(2, 2)),
        2.0 * (-2.0 * y * gr(0, 0) + x * gr(0, 1) + w * gr(0, 2) + x * gr(1, 0) + zq * gr(1, 2)
            - w * gr(2, 0)
            + zq * gr(2, 1)
            - 2.0 * y * gr(2, 2)),
        2.0 * (-2.0 * zq * gr(0, 0) - w * gr(0, 1) + x * gr(0, 2) + w * gr(1, 0)
            - 2.0 * zq * gr(1, 1)
            + y * gr(1, 2)
            + x * gr(2, 0)
            + y * gr(2, 1)),
    ];
    let dot = (0..4).map(|k| geo.qn[k] * dqn[k]).sum::<f64>();
    let q = std::array::from_fn(|k| ((dqn[k] - geo.qn[k] * dot) / geo.q_norm) as f32);

    // Opacity sigmoid.
    let logit = d.opacity * geo.opacity * (1.0 - geo.opacity);

    // SH colour, its clamp, and the view-direction path into the mean.
    let dirv = r.mean - frame.center;
    let len = dirv.length();
    let dir = dirv / len;
    let (basis, dbasis) = sh::basis_and_grad(dir.to_array(), active_degree);
    let (_, raw_rgb) = color(frame, r.mean, r.sh, active_degree);
    let drgb: [f32; 3] = std::array::from_fn(|ch| if raw_rgb[ch] >= 0.0 { d.rgb[ch] } else { 0.0 });
    let mut d_dir = Vec3::ZERO;
    for k in 0..crate::gaussians::sh_coeff_count(active_degree) {
        let mut s = 0.0f32;
        for ch in 0..3 {
            sh_grad[k * 3 + ch] = basis[k] * drgb[ch];
            s += r.sh[k * 3 + ch] * drgb[ch];
        }
        d_dir += Vec3::from_array(dbasis[k]) * s;
    }
    let d_mean = d_mean64.as_vec3() + (d_dir - dir * dir.dot(d_dir)) / len;

    Some(RawGrads {
        mean: d_mean.to_array(),
        log_scale,
        q,
        logit,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn min_sigma_over_rectangle_matches_a_dense_grid() {
        let mut state = 12345u64;
        let mut next = move || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 40) as f32 / (1u64 << 24) as f32
        };
        for _ in 0..200 {
            let (sx, sy, rho) = (0.5 + 20.0 * next(), 0.5 + 20.0 * next(), 1.8 * next() - 0.9);
            let (ca, cc, cb) = (sx * sx, sy * sy, rho * sx * sy);
            let det = ca * cc - cb * cb;
            let s = Splat {
                u: 100.0 * next() - 50.0,
                v: 100.0 * next() - 50.0,
                a: cc / det,
                b: -cb / det,
                c: ca / det,
                ..Splat::default()
            };
            let (x0, y0) = (60.0 * next() - 30.0, 60.0 * next() - 30.0);
            let (x1, y1) = (x0 + 15.0, y0 + 15.0);
            let m = s.min_sigma_over(x0, x1, y0, y1);
            let mut grid = f32::INFINITY;
            for i in 0..=150 {
                for j in 0..=150 {
                    let x = x0 + (x1 - x0) * i as f32 / 150.0;
                    let y = y0 + (y1 - y0) * j as f32 / 150.0;
                    grid = grid.min(s.sigma_at(x - s.u, y - s.v));
                }
            }
            assert!(
                m <= grid * (1.0 + 1e-5) + 1e-6,
                "{m} above grid minimum {grid}"
            );
            assert!(m >= grid * 0.95 - 1e-2, "{m} far below grid minimum {grid}");
        }
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig { cases: 256, ..Default::default() })]

        /// The tiles `for_each_touched_tile` lists are those `touches_tile` keeps, in ascending
        /// order: round and needle-thin conics, means inside and outside the rectangle, partial
        /// edge tiles, and rectangles wider than the hoisted columns.
        #[test]
        fn touched_tiles_are_those_touches_tile_keeps(
            (log_sx, log_sy, rho) in (-3.0f32..6.0, -3.0f32..6.0, -0.9999f32..0.9999),
            (fu, fv) in (-0.5f32..1.5, -0.5f32..1.5),
            opacity in 0.004f32..1.0,
            (width, height) in (1u32..1200, 1u32..800),
            (x, y, w, h) in (0u32..80, 0u32..50, 0u32..80, 0u32..50),
        ) {
            let cam = splat_core::Camera::look_at(
                width,
                height,
                0.8,
                Vec3::new(0.0, 0.0, -4.0),
                Vec3::ZERO,
                Vec3::Y,
            );
            let frame = Frame::new(&cam);
            let (tx1, ty1) = (frame.tiles_x - 1, frame.tiles_y - 1);
            let (x0, y0) = (x.min(tx1), y.min(ty1));
            let rect = [x0, y0, (x0 + w).min(tx1), (y0 + h).min(ty1)];
            // The mean near the rectangle and extents from a fraction of a tile to many tiles,
            // so that many tiles lie on the ellipse's boundary.
            let (sx, sy) = (log_sx.exp(), log_sy.exp());
            let (ca, cc, cb) = (sx * sx, sy * sy, rho * sx * sy);
            let det = ca * cc - cb * cb;
            let span =
                |lo: u32, hi: u32, f: f32| (lo * TILE) as f32 + f * ((hi - lo + 1) * TILE) as f32;
            let s = Splat {
                u: span(rect[0], rect[2], fu),
                v: span(rect[1], rect[3], fv),
                a: cc / det,
                b: -cb / det,
                c: ca / det,
                sigma_cut: (255.0 * opacity).ln().max(0.0),
                ..Splat::default()
            };
            let mut listed = Vec::new();
            s.for_each_touched_tile(&frame, rect, |tx, ty| listed.push((ty, tx)));
            let kept: Vec<(u32, u32)> = (rect[1]..=rect[3])
                .flat_map(|ty| (rect[0]..=rect[2]).map(move |tx| (ty, tx)))
                .filter(|&(ty, tx)| s.touches_tile(&frame, tx, ty))
                .collect();
            proptest::prop_assert_eq!(listed, kept);
        }
    }
}
