//! Finite-difference check of the trainer's appearance deformation through the rasterizer: for
//! `L(d) = Σ_pixels w · render(canonical + d)` (opacity logit + Δopacity, SH DC + Δcolour), the
//! appearance columns of the rows `deformation_gradient` builds from the rasterizer's backward
//! match central differences of L (summed in f64). The geometric columns are the rasterizer's
//! own gradients (checked against f64 differences in splat-raster; their order in the row is
//! checked by `splat_core::deformed`'s proptest, for every layout).

use glam::Vec3;
use splat_core::{Component, DeformedGeometry, Layout, deformation_gradient};
use splat_raster::{Camera, CpuRasterizer, Gaussians, PixelGrads, Rasterizer, RenderOptions};

const N: usize = 4;

fn scene() -> Gaussians {
    let mut g = Gaussians::with_degree(1);
    let spots = [
        [0.0, 0.0, 0.0],
        [0.25, 0.1, 0.05],
        [-0.2, -0.15, 0.1],
        [0.05, -0.25, -0.1],
    ];
    for (i, m) in spots.iter().enumerate() {
        g.means.push(*m);
        g.log_scales.push([-1.8, -2.0, -1.9]);
        g.rotations.push([1.0, 0.1 * i as f32, -0.05, 0.02]);
        g.opacity_logits.push(-0.3 + 0.2 * i as f32);
        let mut sh = vec![0.0f32; 12];
        sh[..3].copy_from_slice(&[0.2, -0.1 + 0.05 * i as f32, 0.3]);
        sh[3..]
            .iter_mut()
            .enumerate()
            .for_each(|(k, v)| *v = 0.02 * (k as f32 - 4.0));
        g.sh.extend(sh);
    }
    g
}

fn camera() -> Camera {
    Camera::look_at(20, 16, 0.9, Vec3::new(0.4, -1.6, 0.5), Vec3::ZERO, Vec3::Z)
}

fn weights(pixels: usize) -> Vec<[f32; 3]> {
    (0..pixels)
        .map(|p| {
            let x = p as f32;
            [(x * 0.37).sin(), (x * 0.11).cos(), (x * 0.23).sin() * 0.5]
        })
        .collect()
}

fn loss(g: &Gaussians, d: &[f32], layout: Layout) -> f64 {
    loss_of(&DeformedGeometry::new(g, Some(d), layout), g)
}

fn loss_of(geometry: &DeformedGeometry, g: &Gaussians) -> f64 {
    let cam = camera();
    let opts = RenderOptions {
        background: [0.1, 0.2, 0.3],
        sh_degree: None,
    };
    let out = CpuRasterizer::new()
        .forward(geometry.view(g), &cam, &opts)
        .unwrap();
    let w = weights(out.color.len());
    out.color
        .iter()
        .zip(&w)
        .map(|(c, w)| {
            (0..3)
                .map(|k| f64::from(c[k]) * f64::from(w[k]))
                .sum::<f64>()
        })
        .sum()
}

#[test]
fn appearance_columns_match_finite_differences() {
    let g = scene();
    let layout = Layout::ALL;
    let dim = layout.dim();
    let d: Vec<f32> = (0..N * dim)
        .map(|e| 0.02 * ((e * 7 % 11) as f32 - 5.0) / 5.0)
        .collect();
    let geometry = DeformedGeometry::new(&g, Some(&d), layout);
    let cam = camera();
    let opts = RenderOptions {
        background: [0.1, 0.2, 0.3],
        sh_degree: None,
    };
    let raster = CpuRasterizer::new();
    let fwd = raster.forward(geometry.view(&g), &cam, &opts).unwrap();
    assert!(
        fwd.radii().iter().all(|&r| r > 0.0),
        "every Gaussian is visible"
    );
    let w = weights(fwd.color.len());
    let grads = raster
        .backward(
            geometry.view(&g),
            &cam,
            &opts,
            &fwd,
            PixelGrads::from_color(&w),
        )
        .unwrap()
        .grads;
    let rows = deformation_gradient(&grads, g.sh_stride(), layout);
    assert_eq!(rows.len(), N * dim);
    let range = |c| layout.range(c).unwrap();
    for (i, row) in rows.chunks_exact(dim).enumerate() {
        assert_eq!(&row[range(Component::Position)], &grads.means[i]);
        assert_eq!(row[range(Component::Opacity)], [grads.opacity_logits[i]]);
        assert_eq!(
            &row[range(Component::Colour)],
            &grads.sh[i * 12..i * 12 + 3]
        );
    }
    let eps = 1e-3f32;
    let mut largest_appearance = 0.0f64;
    let appearance = layout.offset(Component::Opacity).unwrap();
    for e in (0..N * dim).filter(|e| e % dim >= appearance) {
        let col = e % dim;
        let mut plus = d.clone();
        plus[e] += eps;
        let mut minus = d.clone();
        minus[e] -= eps;
        let fd = (loss(&g, &plus, layout) - loss(&g, &minus, layout)) / (2.0 * f64::from(eps));
        let a = f64::from(rows[e]);
        assert!(
            (a - fd).abs() <= 2e-3 + 2e-2 * a.abs().max(fd.abs()),
            "Gaussian {} column {col}: analytic {a} vs finite difference {fd}",
            e / dim
        );
        largest_appearance = largest_appearance.max(a.abs());
    }
    assert!(largest_appearance > 1e-2, "appearance gradients ~0");
}

#[test]
fn components_a_layout_leaves_out_are_the_canonical_ones() {
    let g = scene();
    let canonical = |layout: Layout| loss(&g, &vec![0.0f32; N * layout.dim()], layout);
    let base = loss_of(&DeformedGeometry::new(&g, None, Layout::ALL), &g);
    // Zero rows of any layout render the canonical Gaussians.
    for layout in [Layout::GEOMETRY, Layout::ALL, opacity_only()] {
        assert_eq!(canonical(layout), base, "`{layout}`");
    }
    // Rows of opacity alone move nothing else, yet change the render.
    let rows = vec![3.0f32; N];
    let deformed = DeformedGeometry::new(&g, Some(&rows), opacity_only());
    assert_eq!(deformed.means, g.means);
    assert_eq!(deformed.rotations, g.rotations);
    assert_eq!(deformed.log_scales, g.log_scales);
    assert!(deformed.sh.is_none());
    assert_ne!(loss(&g, &rows, opacity_only()), base);
}

fn opacity_only() -> Layout {
    Layout {
        opacity: true,
        ..Layout::from_bits(0).unwrap()
    }
}
