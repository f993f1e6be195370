// Projection backward (one thread per Gaussian): chains the record gradient accumulated by the
// backward compositing to the raw parameters, as cpu/project.rs `project_backward`, but in f32 and
// through T = J W R S (Sigma2d = T T^T + 0.3 I) instead of the camera-space covariance, so that
// no squared scale is ever formed.
//
// Output per Gaussian (14 floats): d mean (3), d log-scale (3), d quaternion (4), d logit,
// d u, d v (pixels), and 1.0 when a non-finite gradient was zeroed. SH gradients go to `sh_out`.

@group(0) @binding(2) var<storage, read> splats: array<Splat>;
@group(0) @binding(3) var<storage, read> grads: array<f32>;
@group(0) @binding(4) var<storage, read_write> out: array<f32>;
@group(0) @binding(5) var<storage, read_write> sh_out: array<f32>;

const OUT_STRIDE: u32 = 14u;

fn zero_out(i: u32) {
    for (var k = 0u; k < OUT_STRIDE; k++) {
        out[i * OUT_STRIDE + k] = 0.0;
    }
    for (var k = 0u; k < frame.sh_stride; k++) {
        sh_out[i * frame.sh_stride + k] = 0.0;
    }
}

@compute @workgroup_size(256)
fn project_backward(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>) {
    let i = gid.x + gid.y * nwg.x * 256u;
    if i >= frame.n {
        return;
    }
    zero_out(i);
    if splats[i].opacity <= 0.0 {
        return;
    }
    var geo = geometry(i);
    if geo.reason != 0u {
        return;
    }
    let gb = i * 10u;
    let du = grads[gb];
    let dv = grads[gb + 1u];
    let fx = frame.fx;
    let fy = frame.fy;
    let z = geo.z;
    var dp = vec3<f32>(0.0, 0.0, grads[gb + 9u]);
    dp.x += du * fx / z;
    dp.y += dv * fy / z;
    dp.z += -du * fx * geo.rx / z - dv * fy * geo.ry / z;

    // Conic Q = Sigma2d^-1, G_Sigma2d = -Q G_Q Q with G_Q = [[ga, gb/2], [gb/2, gc]], and
    // Sigma2d = T T^T + 0.3 I, so dT = 2 G T = -2 Q G_Q (Q T). Formed naively in f32 this
    // cancels badly for Gaussians elongated along the view ray (Q large, Q T small), so Q T is
    // computed from the 2x2 minors of T: (adj Sigma2d) t_c = (sum_k T1k m_ck + 0.3 T0c,
    // -sum_k T0k m_ck + 0.3 T1c) with m_ck = T0c T1k - T0k T1c; and every contraction of dT
    // with T (the log-scale gradient, the depth scaling of J) as -2 (G_Q Q t_c) . (Q t_c).
    let qa = (geo.cn + DILATION * geo.ik2) / geo.dk;
    let qb = -geo.bn / geo.dk;
    let qc = (geo.an + DILATION * geo.ik2) / geo.dk;
    let ga = grads[gb + 2u];
    let gbh = 0.5 * grads[gb + 3u];
    let gc = grads[gb + 4u];
    let tn0 = geo.t0 / geo.k;
    let tn1 = geo.t1 / geo.k;
    var dt0 = vec3<f32>(0.0);
    var dt1 = vec3<f32>(0.0);
    var d_log_scale = vec3<f32>(0.0);
    for (var c = 0u; c < 3u; c++) {
        var s0 = 0.0;
        var s1 = 0.0;
        for (var kk = 0u; kk < 3u; kk++) {
            let km = geo.k * (tn0[c] * tn1[kk] - tn0[kk] * tn1[c]);
            s0 += tn1[kk] * km;
            s1 -= tn0[kk] * km;
        }
        let w0 = (s0 + DILATION * tn0[c] / geo.k) / geo.dk;
        let w1 = (s1 + DILATION * tn1[c] / geo.k) / geo.dk;
        let x0 = ga * w0 + gbh * w1;
        let x1 = gbh * w0 + gc * w1;
        dt0[c] = -2.0 * (qa * x0 + qb * x1);
        dt1[c] = -2.0 * (qb * x0 + qc * x1);
        d_log_scale[c] = -2.0 * (x0 * w0 + x1 * w1);
    }
    // T = J V: dJ = dT V^T. With S = sum_c dT_c . t_c = dJ0 . j0 + dJ1 . j1, the CPU's chain
    // through J = (1/z) [[fx, 0, -fx rxc], [0, fy, -fy ryc]] becomes dp.z += -S / z plus the
    // terms of the unclamped x/z and y/z.
    let gj0 = dt0.x * geo.v[0] + dt0.y * geo.v[1] + dt0.z * geo.v[2];
    let gj1 = dt1.x * geo.v[0] + dt1.y * geo.v[1] + dt1.z * geo.v[2];
    let j0 = vec3<f32>(fx / z, 0.0, -fx * geo.rxc / z);
    let j1 = vec3<f32>(0.0, fy / z, -fy * geo.ryc / z);
    let z2 = z * z;
    dp.z += -(d_log_scale.x + d_log_scale.y + d_log_scale.z) / z;
    if geo.rx == geo.rxc {
        dp.x += -gj0.z * fx / z2;
        dp.z += gj0.z * fx * geo.rx / z2;
    }
    if geo.ry == geo.ryc {
        dp.y += -gj1.z * fy / z2;
        dp.z += gj1.z * fy * geo.ry / z2;
    }
    let wt = transpose(mat3x3<f32>(
        vec3<f32>(frame.w00, frame.w10, frame.w20),
        vec3<f32>(frame.w01, frame.w11, frame.w21),
        vec3<f32>(frame.w02, frame.w12, frame.w22),
    ));
    let d_mean_geo = wt * dp;

    // V = W R S: dM = W^T dV with dV col c = j0 dT0[c] + j1 dT1[c]; the rotation part.
    var g_rot: mat3x3<f32>;
    for (var c = 0u; c < 3u; c++) {
        let dm = wt * (j0 * dt0[c] + j1 * dt1[c]);
        g_rot[c] = dm * geo.scale[c];
    }
    let w = geo.qn.x;
    let x = geo.qn.y;
    let y = geo.qn.z;
    let zq = geo.qn.w;
    // gr(i, j): row i, column j.
    let r00 = g_rot[0].x;
    let r01 = g_rot[1].x;
    let r02 = g_rot[2].x;
    let r10 = g_rot[0].y;
    let r11 = g_rot[1].y;
    let r12 = g_rot[2].y;
    let r20 = g_rot[0].z;
    let r21 = g_rot[1].z;
    let r22 = g_rot[2].z;
    let dqn = vec4<f32>(
        2.0 * (-zq * r01 + y * r02 + zq * r10 - x * r12 - y * r20 + x * r21),
        2.0 * (y * r01 + zq * r02 + y * r10 - 2.0 * x * r11 - w * r12 + zq * r20 + w * r21 - 2.0 * x * r22),
        2.0 * (-2.0 * y * r00 + x * r01 + w * r02 + x * r10 + zq * r12 - w * r20 + zq * r21 - 2.0 * y * r22),
        2.0 * (-2.0 * zq * r00 - w * r01 + x * r02 + w * r10 - 2.0 * zq * r11 + y * r12 + x * r20 + y * r21),
    );
    let d_q = (dqn - geo.qn * dot(geo.qn, dqn)) / geo.q_norm;
    let d_logit = grads[gb + 5u] * geo.opacity * (1.0 - geo.opacity);

    // SH colour, its clamp, and the view-direction path into the mean.
    let mean = vec3<f32>(param(i, 0u), param(i, 1u), param(i, 2u));
    let dirv = view_dir(mean);
    let len = sqrt(dot(dirv, dirv));
    let dir = dirv / len;
    var basis = sh_basis(dir, frame.active_degree);
    let raw = raw_color(i, unit(dirv));
    let d_rgb_in = vec3<f32>(grads[gb + 6u], grads[gb + 7u], grads[gb + 8u]);
    let d_rgb = select(vec3<f32>(0.0), d_rgb_in, raw >= vec3<f32>(0.0));
    var d_dir = vec3<f32>(0.0);
    let count = (frame.active_degree + 1u) * (frame.active_degree + 1u);
    var sh_finite = true;
    for (var k = 0u; k < count; k++) {
        var s = 0.0;
        for (var ch = 0u; ch < 3u; ch++) {
            let gsh = basis.b[k] * d_rgb[ch];
            sh_out[i * frame.sh_stride + k * 3u + ch] = gsh;
            sh_finite = sh_finite && finite(gsh);
            s += param(i, 11u + k * 3u + ch) * d_rgb[ch];
        }
        d_dir += basis.g[k] * s;
    }
    let d_mean = d_mean_geo + (d_dir - dir * dot(dir, d_dir)) / len;

    let ok = finite3(d_mean) && finite3(d_log_scale) && finite(d_q.x) && finite(d_q.y) && finite(d_q.z)
        && finite(d_q.w) && finite(d_logit) && sh_finite && finite(du) && finite(dv);
    let o = i * OUT_STRIDE;
    if !ok {
        zero_out(i);
        out[o + 13u] = 1.0;
        return;
    }
    out[o] = d_mean.x;
    out[o + 1u] = d_mean.y;
    out[o + 2u] = d_mean.z;
    out[o + 3u] = d_log_scale.x;
    out[o + 4u] = d_log_scale.y;
    out[o + 5u] = d_log_scale.z;
    out[o + 6u] = d_q.x;
    out[o + 7u] = d_q.y;
    out[o + 8u] = d_q.z;
    out[o + 9u] = d_q.w;
    out[o + 10u] = d_logit;
    out[o + 11u] = du;
    out[o + 12u] = dv;
}
