//! The viewer's page in a real browser: headless Chromium (Debian's `chromium`, installed by
//! `scripts/test`) driven through the DevTools protocol. Loads the page on a tiny trained run,
//! drags to orbit, moves the time slider, and checks from screenshots that the view changed and
//! equals the server's render at the page's camera and time (the page in its PNG test mode, so
//! the comparison is lossless).

use crate::support;

use std::ffi::OsStr;
use std::path::PathBuf;
use std::time::{Duration, Instant};

use headless_chrome::protocol::cdp::{Input, Page};
use headless_chrome::{Browser, LaunchOptions, Tab};
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

/// Evaluates `js` in the page; its value comes back through JSON (objects included).
fn eval(tab: &Tab, js: &str) -> serde_json::Value {
    let text = tab
        .evaluate(&format!("JSON.stringify({js})"), false)
        .unwrap_or_else(|e| panic!("{js}: {e}"))
        .value;
    match text {
        Some(serde_json::Value::String(t)) => serde_json::from_str(&t).unwrap(),
        _ => serde_json::Value::Null,
    }
}

fn wait_settled(tab: &Tab) {
    let start = Instant::now();
    while eval(tab, "!!(window.evogsView && window.evogsView.settled())") != true {
        assert!(
            start.elapsed() < Duration::from_secs(120),
            "the page did not settle: {}",
            eval(tab, "document.getElementById('stats').textContent")
        );
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// The element's box in CSS pixels: (x, y, width, height).
fn rect(tab: &Tab, selector: &str) -> (f64, f64, f64, f64) {
    let v = eval(
        tab,
        &format!(
            "(() => {{ const r = document.querySelector('{selector}').getBoundingClientRect(); \
             return [r.x, r.y, r.width, r.height]; }})()"
        ),
    );
    let n = |k: usize| v[k].as_f64().unwrap();
    (n(0), n(1), n(2), n(3))
}

fn screenshot(tab: &Tab, selector: &str) -> image::RgbImage {
    let (x, y, width, height) = rect(tab, selector);
    let png = tab
        .capture_screenshot(
            Page::CaptureScreenshotFormatOption::Png,
            None,
            Some(Page::Viewport {
                x,
                y,
                width,
                height,
                scale: 1.0,
            }),
            true,
        )
        .unwrap();
    image::load_from_memory(&png).unwrap().to_rgb8()
}

fn mouse(tab: &Tab, kind: Input::DispatchMouseEventTypeOption, x: f64, y: f64) {
    let pressed = !matches!(kind, Input::DispatchMouseEventTypeOption::MouseReleased);
    tab.call_method(Input::DispatchMouseEvent {
        Type: kind,
        x,
        y,
        modifiers: None,
        timestamp: None,
        button: Some(Input::MouseButton::Left),
        buttons: Some(if pressed { 1 } else { 0 }),
        click_count: Some(1),
        force: None,
        tangential_pressure: None,
        tilt_x: None,
        tilt_y: None,
        twist: None,
        delta_x: None,
        delta_y: None,
        pointer_Type: None,
    })
    .unwrap();
}

/// The page's current full-resolution view as the server renders it.
fn server_view(v: &Viewer, tab: &Tab) -> image::RgbImage {
    let url = eval(tab, "window.evogsView.urls()[0]");
    let url = url.as_str().unwrap();
    assert!(url.contains("fmt=png"), "{url}");
    v.get(url).image()
}

fn assert_shows(v: &Viewer, tab: &Tab, shot: &image::RgbImage, what: &str) {
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
    let args: Vec<&OsStr> = [
        "--disable-gpu",
        "--disable-background-networking",
        "--disable-component-update",
        "--no-first-run",
        // No name resolves: the page can reach nothing but the viewer's loopback address.
        "--host-resolver-rules=MAP * ~NOTFOUND, EXCLUDE 127.0.0.1",
    ]
    .iter()
    .map(OsStr::new)
    .collect();
    let browser = Browser::new(
        LaunchOptions::default_builder()
            .path(Some(chromium()))
            .headless(true)
            .sandbox(false)
            .window_size(Some((900, 700)))
            .user_data_dir(Some(profile.path().to_path_buf()))
            .args(args)
            .idle_browser_timeout(Duration::from_secs(300))
            .build()
            .unwrap(),
    )
    .unwrap();
    let tab = browser.new_tab().unwrap();
    tab.navigate_to(&format!("{}/?png=1", v.base()))
        .unwrap()
        .wait_until_navigated()
        .unwrap();
    wait_settled(&tab);

    // The first view: test camera 0 with its ground truth beside it.
    let state = eval(&tab, "window.evogsView.state()");
    assert_eq!(state["dataset"]["split"], "test", "{state}");
    assert!(
        eval(&tab, "window.evogsView.urls()[0]")
            .as_str()
            .unwrap()
            .contains("cam=dataset:test:0")
    );
    let first = screenshot(&tab, "#img-0");
    assert_eq!(first.dimensions(), (32, 32));
    assert_shows(&v, &tab, &first, "the first view");
    assert_eq!(
        eval(&tab, "document.getElementById('gt-figure').hidden"),
        false
    );
    assert_eq!(
        eval(&tab, "document.getElementById('img-gt').naturalWidth"),
        32
    );
    let stats = eval(&tab, "document.querySelector('figcaption').textContent");
    assert!(stats.as_str().unwrap().contains("Gaussians"), "{stats}");

    // Drag to orbit.
    let (x, y, w, h) = rect(&tab, "#view-0");
    let (cx, cy) = (x + w / 2.0, y + h / 2.0);
    use Input::DispatchMouseEventTypeOption as M;
    mouse(&tab, M::MouseMoved, cx, cy);
    mouse(&tab, M::MousePressed, cx, cy);
    for k in 1..=8 {
        mouse(
            &tab,
            M::MouseMoved,
            cx + 6.0 * k as f64,
            cy + 1.5 * k as f64,
        );
        std::thread::sleep(Duration::from_millis(30));
    }
    mouse(&tab, M::MouseReleased, cx + 48.0, cy + 12.0);
    wait_settled(&tab);
    let state = eval(&tab, "window.evogsView.state()");
    assert!(
        state["dataset"].is_null(),
        "the camera left the dataset's: {state}"
    );
    let orbited = screenshot(&tab, "#img-0");
    let (moved, _) = diff(&first, &orbited);
    assert!(
        moved > 1.0,
        "orbiting did not change the view (mean difference {moved})"
    );
    assert_shows(&v, &tab, &orbited, "after orbiting");
    assert_eq!(
        eval(&tab, "document.getElementById('gt-figure').hidden"),
        true
    );

    // Move the time slider: click at three quarters of its width.
    let t0 = state["t"].as_f64().unwrap();
    let (x, y, w, h) = rect(&tab, "#time");
    tab.click_point(headless_chrome::browser::tab::point::Point {
        x: x + 0.75 * w,
        y: y + h / 2.0,
    })
    .unwrap();
    wait_settled(&tab);
    let t1 = eval(&tab, "window.evogsView.state().t").as_f64().unwrap();
    assert!(
        (t1 - t0).abs() > 0.3 && (0.5..=1.0).contains(&t1),
        "t {t0} -> {t1}"
    );
    let later = screenshot(&tab, "#img-0");
    assert_shows(&v, &tab, &later, "after moving the time slider");
    let (changed, _) = diff(&orbited, &later);
    assert!(
        changed > 0.1,
        "the scene did not move in time (mean difference {changed})"
    );
    let url = eval(&tab, "window.evogsView.urls()[0]");
    assert!(url.as_str().unwrap().contains(&format!("t={t1}")), "{url}");
}
