//! `Background::Random`: a training step scores the render over the iteration's colour against
//! the view's image over the same colour (as if the file had been loaded over it), and the
//! transmittance's errors name the file.

use std::path::{Path, PathBuf};

use evogs_io::Split;
use evogs_metrics::{ImageSize, mse, psnr_from_mse};
use evogs_train::data::{load_split, load_transmittance};
use evogs_train::{Background, Preset, TrainConfig, Trainer};
use splat_raster::{CpuRasterizer, Rasterizer, RenderOptions};

/// evogs-io's lego fixture: three 100×100 RGBA training views.
fn lego_fixture() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../evogs-io/tests/data/dnerf-lego")
}

#[test]
fn a_random_background_step_scores_the_render_against_the_image_over_its_colour() {
    let data = lego_fixture();
    let mut c = TrainConfig::preset(Preset::Tiny);
    c.background = Background::Random;
    c.downscale = 1.0;
    c.init_points = 300;
    let views = load_split(&data, Split::Train, c.time_from, c.background.rgb(), 1.0).unwrap();
    let mut trainer = Trainer::new(c.clone(), views).unwrap();
    // Iteration 1 is static (warm-up) at SH degree 0: render the state as the step will.
    let vi = trainer.view_at(1);
    let colour = c.background.at_iteration(c.seed, 1);
    assert!(colour.iter().any(|&v| v > 0.05), "{colour:?}");
    let view = trainer.train_views().views[vi].clone();
    let render = |background| {
        let opts = RenderOptions {
            background,
            sh_degree: Some(trainer.state().active_sh()),
        };
        CpuRasterizer::new()
            .forward(trainer.state().gaussians().view(), &view.camera, &opts)
            .unwrap()
            .color
    };
    let (over_colour, over_black) = (render(colour), render([0.0; 3]));
    let loaded_over = |background| {
        load_split(&data, Split::Train, c.time_from, background, 1.0)
            .unwrap()
            .views[vi]
            .image
            .pixels
            .clone()
    };
    let size = ImageSize::new(view.image.width as usize, view.image.height as usize);
    let want = psnr_from_mse(mse(size, &over_colour, &loaded_over(colour)).unwrap());
    let black = psnr_from_mse(mse(size, &over_black, &loaded_over([0.0; 3])).unwrap());
    let step = trainer.step().unwrap();
    assert!(
        (step.psnr - want).abs() < 1e-3,
        "{} against {want}",
        step.psnr
    );
    // Not the black background's figure: the colour made a difference.
    assert!(
        (step.psnr - black).abs() > 0.1,
        "{} against {black}",
        step.psnr
    );
    // Training goes on, finite, and the stored views stay over black for evaluation.
    for _ in 0..20 {
        assert!(trainer.step().unwrap().loss.is_finite());
    }
    assert_eq!(
        trainer.train_views().views[vi].image.pixels,
        loaded_over([0.0; 3])
    );
}

#[test]
fn transmittance_errors_name_the_file() {
    let data = lego_fixture();
    let mut views = load_split(&data, Split::Train, Default::default(), [0.0; 3], 1.0).unwrap();
    // A view whose image is not its file's size at the factor.
    let err = load_transmittance(&views, 0.5).unwrap_err().to_string();
    assert!(err.contains("r_0.png") && err.contains("pixels"), "{err}");
    views.views[0].path = data.join("train/absent.png");
    let err = load_transmittance(&views, 1.0).unwrap_err().to_string();
    assert!(err.contains("absent.png"), "{err}");
}

/// The sizes the memory check reads from the dataset's cameras before any image is loaded are
/// the loaded views' (views, pixels after resizing, distinct times), at full size and at a
/// factor whose resize rounds.
#[test]
fn the_sizes_read_before_loading_are_the_loaded_views() {
    use evogs_train::data::open_dataset;
    use evogs_train::memory::DataSizes;
    let data = lego_fixture();
    let dataset = open_dataset(&data, Default::default()).unwrap();
    for factor in [1.0, 0.5, 0.37] {
        let views = load_split(&data, Split::Train, Default::default(), [0.0; 3], factor).unwrap();
        assert_eq!(
            DataSizes::of_split(&dataset, Split::Train, factor),
            DataSizes::of_views(&views),
            "factor {factor}"
        );
    }
}
