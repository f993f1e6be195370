//! The viewer's page in a real browser: headless Chromium (Debian's `chromium`, installed by
//! `scripts/test`) driven through the DevTools protocol ([`support::cdp`]). Loads the page on a
//! tiny trained run, drags to orbit, moves the time slider, and checks from screenshots that the
//! view changed and equals the server's render at the page's camera and time (the page in its PNG
//! test mode, so the comparison is lossless).

use crate::support;

use std::path::PathBuf;
use std::time::{Duration, Instant};

use support::cdp::Chromium;
use support::diff;
use support::s;
use support::view::{ReplyImage, Viewer, fixture};

/// The Chromium binary: `$EVOGS_CHROMIUM`, or Debian's.
fn chromium() -> PathBuf {
    let path = std::env::var_os("EVOGS_CHROMIUM")
        .map_or_else(|| PathBuf::from("/usr/bin/chromium"), PathBuf::from);
    assert!(
        path.exists(),
        "{}: Chromium is missing (scripts/test installs Debian's `chromium`)",
        path.display()
    );
    path
}

fn wait_settled(tab: &mut Chromium) {
    let start = Instant::now();
    // `None` while the page is still navigating (no context to evaluate in yet).
    while tab.try_eval("!!(window.evogsView && window.evogsView.settled())") != Some(true.into()) {
        assert!(
            start.elapsed() < Duration::from_secs(120),
            "the page did not settle: {:?}",
            tab.try_eval("document.getElementById('stats').textContent")
        );
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// The element's box in CSS pixels: (x, y, width, height).
fn rect(tab: &mut Chromium, selector: &str) -> (f64, f64, f64, f64) {
    let v = tab.eval(&format!(
        "(() => {{ const r = document.querySelector('{selector}').getBoundingClientRect(); \
         return [r.x, r.y, r.width, r.height]; }})()"
    ));
    let n = |k: usize| v[k].as_f64().unwrap();
    (n(0), n(1), n(2), n(3))
}

fn screenshot(tab: &mut Chromium, selector: &str) -> image::RgbImage {
    let clip = rect(tab, selector);
    image::load_from_memory(&tab.screenshot_png(clip))
        .unwrap()
        .to_rgb8()
}

/// The page's current full-resolution view as the server renders it.
fn server_view(v: &Viewer, tab: &mut Chromium) -> image::RgbImage {
    let url = tab.eval("window.evogsView.urls()[0]");
    let url = url.as_str().unwrap();
    assert!(url.contains("fmt=png"), "{url}");
    v.get(url).image()
}

fn assert_shows(v: &Viewer, tab: &mut Chromium, shot: &image::RgbImage, what: &str) {
    let (mean, max) = diff(shot, &server_view(v, tab));
    assert!(
        mean < 0.5 && max <= 3,
        "{what}: the page shows something else than the server's render (mean {mean}, max {max})"
    );
}

#[test]
fn the_page_orbits_and_moves_in_time_showing_the_servers_renders() {
    let f = fixture();
    let v = Viewer::start(&[s(&f.run)]);
    let profile = tempfile::tempdir().unwrap();
    let args = [
        "--disable-gpu",
        "--disable-background-networking",
        "--disable-component-update",
        "--no-first-run",
        // No name resolves: the page can reach nothing but the viewer's loopback address.
        "--host-resolver-rules=MAP * ~NOTFOUND, EXCLUDE 127.0.0.1",
    ];
    let mut tab = Chromium::launch(&chromium(), &args, (900, 700), profile.path());
    tab.navigate(&format!("{}/?png=1", v.base()));
    wait_settled(&mut tab);

    // The first view: test camera 0 with its ground truth beside it.
    let state = tab.eval("window.evogsView.state()");
    assert_eq!(state["dataset"]["split"], "test", "{state}");
    assert!(
        tab.eval("window.evogsView.urls()[0]")
            .as_str()
            .unwrap()
            .contains("cam=dataset:test:0")
    );
    let first = screenshot(&mut tab, "#img-0");
    // A run of 32 × 32 images is drawn at 6× (rendered at that size): small runs are scaled up.
    assert_eq!(first.dimensions(), (192, 192));
    assert_shows(&v, &mut tab, &first, "the first view");
    assert_eq!(
        tab.eval("document.getElementById('gt-figure').hidden"),
        false
    );
    assert_eq!(
        tab.eval("document.getElementById('img-gt').naturalWidth"),
        32
    );
    let stats = tab.eval("document.querySelector('figcaption').textContent");
    assert!(stats.as_str().unwrap().contains("Gaussians"), "{stats}");
    // The method as the papers name it, and the render command with the run's whole path.
    let method = tab.eval("window.evogsView.info().runs[0].label");
    assert!(
        stats.as_str().unwrap().contains(method.as_str().unwrap()),
        "{stats}"
    );
    let command = tab.eval("document.getElementById('command').textContent");
    assert!(
        command
            .as_str()
            .unwrap()
            .contains(&format!("--run {}", s(&f.run))),
        "{command}"
    );

    // Drag to orbit.
    let (x, y, w, h) = rect(&mut tab, "#view-0");
    let (cx, cy) = (x + w / 2.0, y + h / 2.0);
    tab.mouse("mouseMoved", (cx, cy), false);
    tab.mouse("mousePressed", (cx, cy), true);
    for k in 1..=8 {
        tab.mouse(
            "mouseMoved",
            (cx + 6.0 * k as f64, cy + 1.5 * k as f64),
            true,
        );
        std::thread::sleep(Duration::from_millis(30));
    }
    tab.mouse("mouseReleased", (cx + 48.0, cy + 12.0), false);
    wait_settled(&mut tab);
    let state = tab.eval("window.evogsView.state()");
    assert!(
        state["dataset"].is_null(),
        "the camera left the dataset's: {state}"
    );
    let orbited = screenshot(&mut tab, "#img-0");
    let (moved, _) = diff(&first, &orbited);
    assert!(
        moved > 1.0,
        "orbiting did not change the view (mean difference {moved})"
    );
    assert_shows(&v, &mut tab, &orbited, "after orbiting");
    assert_eq!(
        tab.eval("document.getElementById('gt-figure').hidden"),
        true
    );

    // Move the time slider: click at three quarters of its width.
    let t0 = state["t"].as_f64().unwrap();
    let (x, y, w, h) = rect(&mut tab, "#time");
    tab.click((x + 0.75 * w, y + h / 2.0));
    wait_settled(&mut tab);
    let t1 = tab.eval("window.evogsView.state().t").as_f64().unwrap();
    assert!(
        (t1 - t0).abs() > 0.3 && (0.5..=1.0).contains(&t1),
        "t {t0} -> {t1}"
    );
    let later = screenshot(&mut tab, "#img-0");
    assert_shows(&v, &mut tab, &later, "after moving the time slider");
    let (changed, _) = diff(&orbited, &later);
    assert!(
        changed > 0.1,
        "the scene did not move in time (mean difference {changed})"
    );
    let url = tab.eval("window.evogsView.urls()[0]");
    assert!(url.as_str().unwrap().contains(&format!("t={t1}")), "{url}");
}
