// Shared by every kernel (prepended by gpu/pipelines.rs): the frame uniform, the compositing
// record, the constants of DESIGN §3, and the per-Gaussian geometry (f32, cancellation-safe).

// Mirrored by `FrameUniform` in gpu/frame.rs (gpu/layout.rs checks that the layouts agree).
struct Frame {
    fx: f32, fy: f32, cx: f32, cy: f32,
    lim_x0: f32, lim_x1: f32, lim_y0: f32, lim_y1: f32,
    // World-to-camera rotation, row-major.
    w00: f32, w01: f32, w02: f32,
    w10: f32, w11: f32, w12: f32,
    w20: f32, w21: f32, w22: f32,
    t0: f32, t1: f32, t2: f32,
    c0: f32, c1: f32, c2: f32,
    bg0: f32, bg1: f32, bg2: f32,
    width: u32, height: u32, tiles_x: u32, tiles_y: u32,
    n: u32, active_degree: u32, param_stride: u32, sh_stride: u32,
    n_isect: u32, use_d_alpha: u32, use_d_depth: u32, pad0: u32,
    pad1: u32, pad2: u32,
}

// One drawn Gaussian's compositing record (opacity 0 when culled).
struct Splat {
    u: f32, v: f32, a: f32, b: f32, c: f32,
    opacity: f32, sigma_cut: f32, z: f32,
    r: f32, g: f32, bl: f32,
    x0: u32, y0: u32, x1: u32, y1: u32,
    pad: u32,
}

@group(0) @binding(0) var<uniform> frame: Frame;
// Raw parameters, `param_stride` floats per Gaussian: mean 3, log-scale 3, quaternion 4, opacity
// logit 1, SH `sh_stride`.
@group(0) @binding(1) var<storage, read> params: array<f32>;

const TILE: u32 = 16u;
const ALPHA_MIN: f32 = 1.0 / 255.0;
const ALPHA_MAX: f32 = 0.99;
const T_MIN: f32 = 1e-4;
const DILATION: f32 = 0.3;
const NEAR_PLANE: f32 = 0.01;
const QUAT_NORM2_MIN: f32 = 1e-12;
const MAX_COLOR: f32 = 1e18;
const F32_MAX: f32 = 3.40282347e38;

// Cull reasons, in the order of CullStats (0 = drawn).
const CULL_NON_FINITE: u32 = 1u;
const CULL_ZERO_QUATERNION: u32 = 2u;
const CULL_LOW_OPACITY: u32 = 3u;
const CULL_BEHIND_NEAR_PLANE: u32 = 4u;
const CULL_DEGENERATE: u32 = 5u;
const CULL_OFF_SCREEN: u32 = 6u;

fn finite(x: f32) -> bool {
    return (bitcast<u32>(x) & 0x7f800000u) != 0x7f800000u;
}

fn finite3(v: vec3<f32>) -> bool {
    return finite(v.x) && finite(v.y) && finite(v.z);
}

fn w_row(f: Frame, i: u32) -> vec3<f32> {
    if i == 0u {
        return vec3<f32>(f.w00, f.w01, f.w02);
    }
    if i == 1u {
        return vec3<f32>(f.w10, f.w11, f.w12);
    }
    return vec3<f32>(f.w20, f.w21, f.w22);
}

fn sigma_at(s: Splat, dx: f32, dy: f32) -> f32 {
    return 0.5 * (s.a * dx * dx + s.c * dy * dy) + s.b * dx * dy;
}

// Smallest sigma over the rectangle [x0, x1] x [y0, y1] (see cpu/project.rs `min_sigma_over`).
fn min_sigma_over(s: Splat, x0: f32, x1: f32, y0: f32, y1: f32) -> f32 {
    let dx0 = x0 - s.u;
    let dx1 = x1 - s.u;
    let dy0 = y0 - s.v;
    let dy1 = y1 - s.v;
    if dx0 <= 0.0 && dx1 >= 0.0 && dy0 <= 0.0 && dy1 >= 0.0 {
        return 0.0;
    }
    var best = F32_MAX;
    for (var e = 0u; e < 2u; e++) {
        let dx = select(dx1, dx0, e == 0u);
        let dy = clamp(-s.b * dx / s.c, dy0, dy1);
        best = min(best, sigma_at(s, dx, dy));
        let dyy = select(dy1, dy0, e == 0u);
        let dxx = clamp(-s.b * dyy / s.a, dx0, dx1);
        best = min(best, sigma_at(s, dxx, dyy));
    }
    return best;
}

// Whether some pixel centre of tile (tx, ty) inside the image may reach sigma <= sigma_cut.
fn touches_tile(f: Frame, s: Splat, tx: u32, ty: u32) -> bool {
    let x0 = tx * TILE;
    let y0 = ty * TILE;
    let x1 = min(x0 + TILE - 1u, f.width - 1u);
    let y1 = min(y0 + TILE - 1u, f.height - 1u);
    let m = min_sigma_over(s, f32(x0) + 0.5, f32(x1) + 0.5, f32(y0) + 0.5, f32(y1) + 0.5);
    return !(m > s.sigma_cut * (1.0 + 1e-4) + 1e-4);
}

fn sigmoid(x: f32) -> f32 {
    return 1.0 / (1.0 + exp(-x));
}

fn rotation(q: vec4<f32>) -> mat3x3<f32> {
    let w = q.x;
    let x = q.y;
    let y = q.z;
    let z = q.w;
    return mat3x3<f32>(
        vec3<f32>(1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y + w * z), 2.0 * (x * z - w * y)),
        vec3<f32>(2.0 * (x * y - w * z), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z + w * x)),
        vec3<f32>(2.0 * (x * z + w * y), 2.0 * (y * z - w * x), 1.0 - 2.0 * (x * x + y * y)),
    );
}

// Per-Gaussian geometry shared by the projection and its backward pass.
//
// Sigma2d = T T^T + 0.3 I with T = J W R S (2x3). T is scaled by k = max(max|T|, 1) so that huge scales
// do not overflow, and det(Sigma2d) / k^2 is formed without cancellation (Cauchy-Binet):
// det(T T^T) = sum of the squared 2x2 minors of T, so
// det / k^2 = sum (k m_ij)^2 + 0.3 tr(Tn Tn^T) + 0.09 / k^2 with Tn = T / k.
struct Geo {
    reason: u32,
    opacity: f32,
    qn: vec4<f32>,
    q_norm: f32,
    rot: mat3x3<f32>,
    scale: vec3<f32>,
    // W R S (columns).
    v: mat3x3<f32>,
    z: f32,
    rx: f32,
    ry: f32,
    rxc: f32,
    ryc: f32,
    // Rows of T (unscaled).
    t0: vec3<f32>,
    t1: vec3<f32>,
    k: f32,
    // Scaled entries: Sigma2d = k^2 (an, bn, cn) + 0.3 I; dk = det(Sigma2d) / k^2.
    an: f32,
    bn: f32,
    cn: f32,
    ik2: f32,
    dk: f32,
}

fn param(i: u32, j: u32) -> f32 {
    return params[i * frame.param_stride + j];
}

fn geometry(i: u32) -> Geo {
    var g: Geo;
    g.reason = 0u;
    var all_finite = true;
    for (var j = 0u; j < frame.param_stride; j++) {
        all_finite = all_finite && finite(param(i, j));
    }
    if !all_finite {
        g.reason = CULL_NON_FINITE;
        return g;
    }
    let q = vec4<f32>(param(i, 6u), param(i, 7u), param(i, 8u), param(i, 9u));
    let qm = max(max(abs(q.x), abs(q.y)), max(abs(q.z), abs(q.w)));
    if qm < 1e-6 && dot(q, q) < QUAT_NORM2_MIN {
        g.reason = CULL_ZERO_QUATERNION;
        return g;
    }
    let qs = q / qm;
    let ns = sqrt(dot(qs, qs));
    g.qn = qs / ns;
    g.q_norm = qm * ns;
    g.opacity = sigmoid(param(i, 10u));
    if g.opacity < ALPHA_MIN {
        g.reason = CULL_LOW_OPACITY;
        return g;
    }
    let mean = vec3<f32>(param(i, 0u), param(i, 1u), param(i, 2u));
    let big = max(max(max(abs(mean.x), abs(mean.y)), abs(mean.z)), 1.0);
    let ms = mean / big;
    let t = vec3<f32>(frame.t0, frame.t1, frame.t2) / big;
    let p = vec3<f32>(
        dot(w_row(frame, 0u), ms) + t.x,
        dot(w_row(frame, 1u), ms) + t.y,
        dot(w_row(frame, 2u), ms) + t.z,
    );
    g.z = p.z * big;
    if g.z <= NEAR_PLANE {
        g.reason = CULL_BEHIND_NEAR_PLANE;
        return g;
    }
    g.rx = p.x / p.z;
    g.ry = p.y / p.z;
    g.rxc = clamp(g.rx, frame.lim_x0, frame.lim_x1);
    g.ryc = clamp(g.ry, frame.lim_y0, frame.lim_y1);
    g.rot = rotation(g.qn);
    g.scale = exp(vec3<f32>(param(i, 3u), param(i, 4u), param(i, 5u)));
    let wm = mat3x3<f32>(
        vec3<f32>(frame.w00, frame.w10, frame.w20),
        vec3<f32>(frame.w01, frame.w11, frame.w21),
        vec3<f32>(frame.w02, frame.w12, frame.w22),
    );
    let wr = wm * g.rot;
    g.v = mat3x3<f32>(wr[0] * g.scale.x, wr[1] * g.scale.y, wr[2] * g.scale.z);
    let jx = frame.fx / g.z;
    let jy = frame.fy / g.z;
    // T row a, column c: j_a . V col c.
    g.t0 = vec3<f32>(
        jx * (g.v[0].x - g.rxc * g.v[0].z),
        jx * (g.v[1].x - g.rxc * g.v[1].z),
        jx * (g.v[2].x - g.rxc * g.v[2].z),
    );
    g.t1 = vec3<f32>(
        jy * (g.v[0].y - g.ryc * g.v[0].z),
        jy * (g.v[1].y - g.ryc * g.v[1].z),
        jy * (g.v[2].y - g.ryc * g.v[2].z),
    );
    // Scaled only when large: small entries cannot overflow, and 1 / k^2 must not either.
    let k = max(max(max(max(abs(g.t0.x), abs(g.t0.y)), max(abs(g.t0.z), abs(g.t1.x))), max(abs(g.t1.y), abs(g.t1.z))), 1.0);
    if !finite(k) {
        g.reason = CULL_DEGENERATE;
        return g;
    }
    g.k = k;
    let a0 = g.t0 / k;
    let a1 = g.t1 / k;
    g.an = dot(a0, a0);
    g.bn = dot(a0, a1);
    g.cn = dot(a1, a1);
    let m01 = k * (a0.x * a1.y - a0.y * a1.x);
    let m02 = k * (a0.x * a1.z - a0.z * a1.x);
    let m12 = k * (a0.y * a1.z - a0.z * a1.y);
    let ik = 1.0 / k;
    g.ik2 = ik * ik;
    g.dk = m01 * m01 + m02 * m02 + m12 * m12 + DILATION * (g.an + g.cn) + DILATION * DILATION * g.ik2;
    if !(g.dk > 0.0) {
        g.reason = CULL_DEGENERATE;
        return g;
    }
    return g;
}

// sqrt(|t|^2 + 0.3) (a standard deviation of Sigma2d along an image axis, from one row of T)
// without forming |t|^2, which under- or overflows for rows of very different sizes.
fn axis_sigma(t: vec3<f32>) -> f32 {
    let k = max(max(abs(t.x), abs(t.y)), abs(t.z));
    if k <= 1.0 {
        return sqrt(dot(t, t) + DILATION);
    }
    let n = t / k;
    return k * sqrt(dot(n, n) + DILATION / k / k);
}

// SH basis and its gradient with respect to the unit direction, degree <= 3 (sh.rs).
struct Basis {
    b: array<f32, 16>,
    g: array<vec3<f32>, 16>,
}

fn sh_basis(d: vec3<f32>, degree: u32) -> Basis {
    var o: Basis;
    for (var k = 0u; k < 16u; k++) {
        o.b[k] = 0.0;
        o.g[k] = vec3<f32>(0.0);
    }
    let x = d.x;
    let y = d.y;
    let z = d.z;
    o.b[0] = 0.2820948;
    if degree >= 1u {
        let c1 = 0.48860252;
        o.b[1] = -c1 * y;
        o.g[1] = vec3<f32>(0.0, -c1, 0.0);
        o.b[2] = c1 * z;
        o.g[2] = vec3<f32>(0.0, 0.0, c1);
        o.b[3] = -c1 * x;
        o.g[3] = vec3<f32>(-c1, 0.0, 0.0);
    }
    if degree >= 2u {
        let xx = x * x;
        let yy = y * y;
        let zz = z * z;
        let c0 = 1.0925485;
        let c1 = -1.0925485;
        let c2 = 0.31539157;
        let c3 = -1.0925485;
        let c4 = 0.54627424;
        o.b[4] = c0 * x * y;
        o.g[4] = vec3<f32>(c0 * y, c0 * x, 0.0);
        o.b[5] = c1 * y * z;
        o.g[5] = vec3<f32>(0.0, c1 * z, c1 * y);
        o.b[6] = c2 * (2.0 * zz - xx - yy);
        o.g[6] = vec3<f32>(-2.0 * c2 * x, -2.0 * c2 * y, 4.0 * c2 * z);
        o.b[7] = c3 * x * z;
        o.g[7] = vec3<f32>(c3 * z, 0.0, c3 * x);
        o.b[8] = c4 * (xx - yy);
        o.g[8] = vec3<f32>(2.0 * c4 * x, -2.0 * c4 * y, 0.0);
    }
    if degree >= 3u {
        let xx = x * x;
        let yy = y * y;
        let zz = z * z;
        let c0 = -0.5900436;
        let c1 = 2.8906114;
        let c2 = -0.4570458;
        let c3 = 0.37317633;
        let c4 = -0.4570458;
        let c5 = 1.4453057;
        let c6 = -0.5900436;
        o.b[9] = c0 * y * (3.0 * xx - yy);
        o.g[9] = vec3<f32>(c0 * 6.0 * x * y, c0 * (3.0 * xx - 3.0 * yy), 0.0);
        o.b[10] = c1 * x * y * z;
        o.g[10] = vec3<f32>(c1 * y * z, c1 * x * z, c1 * x * y);
        o.b[11] = c2 * y * (4.0 * zz - xx - yy);
        o.g[11] = vec3<f32>(c2 * (-2.0 * x * y), c2 * (4.0 * zz - xx - 3.0 * yy), c2 * 8.0 * y * z);
        o.b[12] = c3 * z * (2.0 * zz - 3.0 * xx - 3.0 * yy);
        o.g[12] = vec3<f32>(c3 * (-6.0 * x * z), c3 * (-6.0 * y * z), c3 * (6.0 * zz - 3.0 * xx - 3.0 * yy));
        o.b[13] = c4 * x * (4.0 * zz - xx - yy);
        o.g[13] = vec3<f32>(c4 * (4.0 * zz - 3.0 * xx - yy), c4 * (-2.0 * x * y), c4 * 8.0 * x * z);
        o.b[14] = c5 * z * (xx - yy);
        o.g[14] = vec3<f32>(c5 * 2.0 * x * z, c5 * (-2.0 * y * z), c5 * (xx - yy));
        o.b[15] = c6 * x * (xx - 3.0 * yy);
        o.g[15] = vec3<f32>(c6 * (3.0 * xx - 3.0 * yy), c6 * (-6.0 * x * y), 0.0);
    }
    return o;
}

// Unnormalised view direction mean - C and its unit vector as glam computes it (v * (1 / |v|)).
fn view_dir(mean: vec3<f32>) -> vec3<f32> {
    return mean - vec3<f32>(frame.c0, frame.c1, frame.c2);
}

fn unit(v: vec3<f32>) -> vec3<f32> {
    return v * (1.0 / sqrt(dot(v, v)));
}

// Unclamped SH colour of Gaussian i.
fn raw_color(i: u32, dir: vec3<f32>) -> vec3<f32> {
    var basis = sh_basis(dir, frame.active_degree);
    let count = (frame.active_degree + 1u) * (frame.active_degree + 1u);
    var s = vec3<f32>(0.0);
    for (var k = 0u; k < count; k++) {
        let o = 11u + k * 3u;
        s += vec3<f32>(param(i, o), param(i, o + 1u), param(i, o + 2u)) * basis.b[k];
    }
    return vec3<f32>(0.5) + s;
}
