//! Hard cases: needle-thin, huge, behind the camera, at the near plane, zero quaternion, NaN or
//! Inf in any field, arbitrary floats (proptest) — culled and counted, never NaN or Inf out; and
//! bad input rejected with errors that name the field.

use crate::common;

use common::{Q, concat, one};

use glam::{Mat3, Vec3};
use proptest::prelude::*;
use splat_raster::{
    Camera, CpuRasterizer, CullStats, GaussianGrads, Gaussians, PixelGrads, RasterError,
    Rasterizer, RenderOptions,
};

fn camera() -> Camera {
    // At the origin looking down +z (world = camera axes).
    Camera::from_center(40, 30, 35.0, 33.0, 21.0, 14.0, Mat3::IDENTITY, Vec3::ZERO)
}

/// Forward and backward with a dense upstream gradient; asserts everything out is finite.
/// Returns the cull counts, the gradients and the screen radii.
fn render_all_finite(g: &Gaussians, cam: &Camera) -> (CullStats, GaussianGrads, Vec<f32>) {
    let r = CpuRasterizer::new();
    let opts = RenderOptions {
        background: [0.2, 0.4, 0.6],
        sh_degree: None,
    };
    let fwd = r.forward(g.view(), cam, &opts).unwrap();
    assert!(fwd.color.iter().flatten().all(|v| v.is_finite()), "colour");
    assert!(
        fwd.alpha
            .iter()
            .all(|v| v.is_finite() && (0.0..=1.0).contains(v)),
        "alpha"
    );
    assert!(fwd.depth.iter().all(|v| v.is_finite()), "depth");
    let s = fwd.stats;
    assert_eq!(s.drawn + s.culled(), s.total, "{s}");
    let npix = cam.pixel_count();
    let dc = vec![[1.0f32, -0.5, 0.25]; npix];
    let da = vec![0.5f32; npix];
    let dd = vec![-0.1f32; npix];
    let grads = r
        .backward(
            g.view(),
            cam,
            &opts,
            &fwd,
            PixelGrads::from_color(&dc).with_alpha(&da).with_depth(&dd),
        )
        .unwrap()
        .grads;
    let finite = grads
        .means
        .as_flattened()
        .iter()
        .chain(grads.log_scales.as_flattened())
        .chain(grads.rotations.as_flattened())
        .chain(&grads.opacity_logits)
        .chain(&grads.sh)
        .chain(grads.means2d.as_flattened())
        .chain(fwd.radii())
        .all(|v| v.is_finite());
    assert!(finite, "gradients must be finite");
    (s, grads, fwd.radii().to_vec())
}

#[test]
fn needle_thin_and_huge_gaussians_render_finitely() {
    let needle = one(
        [0.1, 0.0, 3.0],
        [-14.0, -14.0, 0.0],
        [0.8, 0.3, 0.4, 0.1],
        2.0,
        1,
    );
    let flat = one(
        [0.0, 0.2, 3.0],
        [-20.0, 0.5, 0.5],
        [0.7, -0.3, 0.2, 0.5],
        2.0,
        1,
    );
    let huge = one([0.0, 0.0, 5.0], [8.0, 8.0, 8.0], Q, 0.0, 1);
    let (s, _, radii) = render_all_finite(&concat(&[needle, flat, huge]), &camera());
    assert_eq!(s.drawn, 3, "{s}");
    assert!(radii.iter().all(|&r| r > 0.0));
    // Scales far beyond f32 squares still render (as a flat wash over the image) ...
    let vast = one([0.0, 0.0, 5.0], [60.0, 0.0, 0.0], Q, 0.0, 1);
    let (s, _, _) = render_all_finite(&vast, &camera());
    assert_eq!(s.drawn, 1, "{s}");
    // ... and a covariance that overflows even f64 is culled, not rendered as NaN.
    let overflow = one([0.0, 0.0, 5.0], [400.0, 0.0, 0.0], Q, 0.0, 1);
    let (s, _, radii) = render_all_finite(&overflow, &camera());
    assert_eq!(s.degenerate_covariance, 1, "{s}");
    assert_eq!(radii[0], 0.0);
}

#[test]
fn behind_camera_and_near_plane_are_culled_and_counted() {
    let behind = one([0.0, 0.0, -2.0], [0.0; 3], Q, 1.0, 0);
    let at_near = one([0.0, 0.0, 0.01], [-2.0; 3], Q, 1.0, 0);
    let at_camera = one([0.0, 0.0, 0.0], [-2.0; 3], Q, 1.0, 0);
    let just_beyond = one([0.0, 0.0, 0.0101], [-2.0; 3], Q, 1.0, 0);
    let (s, _, _) = render_all_finite(
        &concat(&[behind, at_near, at_camera, just_beyond]),
        &camera(),
    );
    assert_eq!(s.behind_near_plane, 3, "{s}");
    assert_eq!(s.drawn, 1, "{s}");
}

#[test]
fn zero_quaternion_and_low_opacity_are_culled_and_counted() {
    let zero = one([0.0, 0.0, 3.0], [-1.0; 3], [0.0; 4], 1.0, 2);
    let tiny = one([0.0, 0.0, 3.0], [-1.0; 3], [1e-7, 0.0, 0.0, 0.0], 1.0, 2);
    let faint = one([0.0, 0.0, 3.0], [-1.0; 3], Q, -6.0, 2);
    let large_q = one([0.0, 0.0, 3.0], [-1.0; 3], [3e30, 1e30, 0.0, 0.0], 1.0, 2);
    let (s, _, _) = render_all_finite(&concat(&[zero, tiny, faint, large_q]), &camera());
    assert_eq!(s.zero_quaternion, 2, "{s}");
    assert_eq!(s.low_opacity, 1, "{s}");
    assert_eq!(s.drawn, 1, "{s}");
}

#[test]
fn nan_or_inf_in_any_field_is_culled_and_counted() {
    let good = one([0.0, 0.0, 3.0], [-1.0; 3], Q, 1.0, 3);
    let mut parts = Vec::new();
    parts.extend(common::poisoned_copies(&good));
    parts.push(good);
    let (s, grads, _) = render_all_finite(&concat(&parts), &camera());
    assert_eq!(s.non_finite, 15, "{s}");
    assert_eq!(s.drawn, 1, "{s}");
    assert!(grads.means[15].iter().any(|&v| v != 0.0));
}

#[test]
fn extreme_colours_are_culled_and_empty_scenes_give_the_background() {
    let mut bright = one([0.0, 0.0, 3.0], [-1.0; 3], Q, 1.0, 0);
    bright.sh = vec![3e38, 3e38, 3e38];
    let mut stack = Vec::new();
    for _ in 0..4 {
        stack.push(bright.clone());
    }
    let (s, _, _) = render_all_finite(&concat(&stack), &camera());
    assert_eq!(s.non_finite, 4, "{s}");
    let empty = Gaussians::with_degree(1);
    let (s, grads, _) = render_all_finite(&empty, &camera());
    assert_eq!((s.total, s.drawn), (0, 0));
    assert!(grads.means.is_empty());
    let out = CpuRasterizer::new()
        .forward(
            empty.view(),
            &camera(),
            &RenderOptions {
                background: [0.25, 0.5, 0.75],
                sh_degree: None,
            },
        )
        .unwrap();
    assert!(out.color.iter().all(|c| *c == [0.25, 0.5, 0.75]));
    assert!(out.alpha.iter().chain(&out.depth).all(|&v| v == 0.0));
}

fn any_float() -> impl Strategy<Value = f32> {
    prop_oneof![
        4 => -3.0f32..3.0,
        1 => proptest::num::f32::ANY,
        1 => Just(f32::NAN),
        1 => prop_oneof![Just(f32::INFINITY), Just(f32::NEG_INFINITY), Just(0.0f32), Just(1e30f32), Just(-1e30f32)],
    ]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]

    #[test]
    fn arbitrary_floats_never_give_nan_or_inf(
        vals in proptest::collection::vec(any_float(), 6 * 14),
        degree in 0u32..=3,
    ) {
        let k = splat_raster::sh_coeff_count(degree);
        let mut parts = Vec::new();
        for c in vals.chunks_exact(14) {
            // Means mostly in front of the camera, so many are drawn.
            let mean = [c[0], c[1], c[2] + 3.0];
            let mut g = one(mean, [c[3] - 1.5, c[4] - 1.5, c[5] - 1.5], [c[6], c[7], c[8], c[9]], c[10], degree);
            for (i, v) in g.sh.iter_mut().enumerate() {
                *v = if i < 3 * k.min(4) { c[11 + i % 3] } else { 0.1 };
            }
            parts.push(g);
        }
        render_all_finite(&concat(&parts), &camera());
    }
}

#[test]
fn bad_input_is_rejected_with_the_field_named() {
    let r = CpuRasterizer::new();
    let opts = RenderOptions::default();
    let cam = camera();
    let g = one([0.0, 0.0, 3.0], [-1.0; 3], Q, 1.0, 1);
    let mut short = g.clone();
    short.opacity_logits.clear();
    let e = r.forward(short.view(), &cam, &opts).unwrap_err();
    assert!(
        matches!(
            e,
            RasterError::LengthMismatch {
                field: "opacity_logits",
                got: 0,
                expected: 1
            }
        ),
        "{e}"
    );
    let mut bad_sh = g.clone();
    bad_sh.sh.pop();
    let e = r.forward(bad_sh.view(), &cam, &opts).unwrap_err();
    assert!(
        e.to_string().contains("sh has 11 entries, expected 12"),
        "{e}"
    );
    let e = r
        .forward(g.view(), &Camera { width: 0, ..cam }, &opts)
        .unwrap_err();
    assert!(
        matches!(
            e,
            RasterError::EmptyImage {
                width: 0,
                height: 30
            }
        ),
        "{e}"
    );
    let e = r
        .forward(
            g.view(),
            &Camera {
                fx: f32::NAN,
                ..cam
            },
            &opts,
        )
        .unwrap_err();
    assert!(e.to_string().contains("fx"), "{e}");
    let e = r
        .forward(
            g.view(),
            &Camera {
                translation: Vec3::new(0.0, f32::INFINITY, 0.0),
                ..cam
            },
            &opts,
        )
        .unwrap_err();
    assert!(e.to_string().contains("translation"), "{e}");
    let more = RenderOptions {
        sh_degree: Some(2),
        ..opts
    };
    let e = r.forward(g.view(), &cam, &more).unwrap_err();
    assert!(
        matches!(
            e,
            RasterError::ActiveShDegree {
                requested: 2,
                available: 1
            }
        ),
        "{e}"
    );
    let nan_bg = RenderOptions {
        background: [0.0, f32::NAN, 0.0],
        ..opts
    };
    assert!(matches!(
        r.forward(g.view(), &cam, &nan_bg),
        Err(RasterError::BadBackground { channel: 1, .. })
    ));
    let mut deg4 = g.clone();
    deg4.sh_degree = 4;
    assert!(matches!(
        r.forward(deg4.view(), &cam, &opts),
        Err(RasterError::ShDegree(4))
    ));

    let fwd = r.forward(g.view(), &cam, &opts).unwrap();
    let npix = cam.pixel_count();
    let dc = vec![[0.0f32; 3]; npix];
    let e = r
        .backward(
            g.view(),
            &cam,
            &opts,
            &fwd,
            PixelGrads::from_color(&dc[1..]),
        )
        .unwrap_err();
    assert!(e.to_string().contains("d_color"), "{e}");
    let mut nan = dc.clone();
    nan[7][2] = f32::NAN;
    let e = r
        .backward(g.view(), &cam, &opts, &fwd, PixelGrads::from_color(&nan))
        .unwrap_err();
    assert!(
        matches!(
            e,
            RasterError::NonFiniteGradient {
                field: "d_color",
                pixel: 7
            }
        ),
        "{e}"
    );
    let e = r
        .backward(
            g.view(),
            &cam,
            &opts,
            &fwd,
            PixelGrads::from_color(&dc).with_alpha(&[0.0; 3]),
        )
        .unwrap_err();
    assert!(e.to_string().contains("d_alpha"), "{e}");
    let two = concat(&[g.clone(), g.clone()]);
    let e = r
        .backward(two.view(), &cam, &opts, &fwd, PixelGrads::from_color(&dc))
        .unwrap_err();
    assert!(matches!(e, RasterError::ForwardMismatch(_)), "{e}");
    let other_bg = RenderOptions {
        background: [1.0; 3],
        ..opts
    };
    let e = r
        .backward(g.view(), &cam, &other_bg, &fwd, PixelGrads::from_color(&dc))
        .unwrap_err();
    assert!(matches!(e, RasterError::ForwardMismatch(_)), "{e}");
}
