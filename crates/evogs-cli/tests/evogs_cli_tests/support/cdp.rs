//! Headless Chromium driven through the Chrome DevTools Protocol over its pipe transport
//! (`--remote-debugging-pipe`: JSON messages ended by a NUL byte, written to the browser's file
//! descriptor 3 and read from its descriptor 4). Only what the viewer's browser test uses: one
//! page, `Runtime.evaluate`, `Page.captureScreenshot` and `Input.dispatchMouseEvent`.
//!
//! Not a general DevTools client. It replaced the `headless_chrome` crate, whose build pulled an
//! HTTP and TLS stack into the test build for a handful of messages (BENCHMARKS.md, "CI").

use std::io::{BufRead, BufReader, Write};
use std::path::Path;
use std::process::{Child, ChildStdin, Command, Stdio};
use std::sync::mpsc::{Receiver, RecvTimeoutError, channel};
use std::time::Duration;

use base64::Engine;
use serde_json::{Value, json};

/// How long one command may wait for its reply before the test fails.
const REPLY_TIMEOUT: Duration = Duration::from_secs(120);

/// A headless Chromium with one page attached; closed and reaped when dropped.
pub struct Chromium {
    child: Child,
    to_browser: ChildStdin,
    from_browser: Receiver<Value>,
    next_id: u64,
    /// The page's flat session, on every page-level command.
    session: String,
}

impl Chromium {
    /// Starts `binary` headless with `args` beside the pipe transport, a `width`×`height` window
    /// and its profile in `profile`, and opens one blank page.
    pub fn launch(
        binary: &Path,
        args: &[&str],
        (width, height): (u32, u32),
        profile: &Path,
    ) -> Self {
        // The pipe transport wants descriptors 3 and 4; a shell moves the child's standard input
        // and output there (no `unsafe` `pre_exec` needed) and gives the browser /dev/null and
        // the test's standard error instead.
        let mut child = Command::new("sh")
            .arg("-c")
            .arg(r#"exec "$0" "$@" 3<&0 4>&1 0</dev/null 1>&2"#)
            .arg(binary)
            .args([
                "--headless",
                "--no-sandbox",
                "--remote-debugging-pipe",
                "--hide-scrollbars",
                "--mute-audio",
            ])
            .arg(format!("--window-size={width},{height}"))
            .arg(format!("--user-data-dir={}", profile.display()))
            .args(args)
            .arg("about:blank")
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .unwrap_or_else(|e| panic!("{}: {e}", binary.display()));
        let to_browser = child.stdin.take().unwrap();
        let mut reader = BufReader::new(child.stdout.take().unwrap());
        let (send, from_browser) = channel();
        // Messages are read on their own thread, so that a browser that stops answering fails
        // the test after `REPLY_TIMEOUT` instead of hanging it.
        std::thread::spawn(move || {
            let mut buf = Vec::new();
            loop {
                buf.clear();
                match reader.read_until(0, &mut buf) {
                    Ok(0) | Err(_) => return,
                    Ok(_) => {}
                }
                if buf.last() == Some(&0) {
                    buf.pop();
                }
                // A message that is not JSON ends the connection (the test then fails on its
                // next reply: "the browser exited").
                let Ok(message) = serde_json::from_slice::<Value>(&buf) else {
                    return;
                };
                if send.send(message).is_err() {
                    return;
                }
            }
        });
        let mut browser = Self {
            child,
            to_browser,
            from_browser,
            next_id: 0,
            session: String::new(),
        };
        let target = browser.browser_call("Target.createTarget", json!({ "url": "about:blank" }));
        let target = target["targetId"].as_str().unwrap().to_owned();
        let attached = browser.browser_call(
            "Target.attachToTarget",
            json!({ "targetId": target, "flatten": true }),
        );
        browser.session = attached["sessionId"].as_str().unwrap().to_owned();
        browser
    }

    /// Sends `method` to the page and returns its reply's `result`, or its `error` as `Err`.
    pub fn try_call(&mut self, method: &str, params: Value) -> Result<Value, Value> {
        let session = self.session.clone();
        self.send(method, params, Some(&session))
    }

    /// [`Self::try_call`], failing the test on an error.
    pub fn call(&mut self, method: &str, params: Value) -> Value {
        self.try_call(method, params)
            .unwrap_or_else(|e| panic!("{method}: {e}"))
    }

    fn browser_call(&mut self, method: &str, params: Value) -> Value {
        self.send(method, params, None)
            .unwrap_or_else(|e| panic!("{method}: {e}"))
    }

    /// Writes one command; returns its id.
    fn write(
        &mut self,
        method: &str,
        params: Value,
        session: Option<&str>,
    ) -> std::io::Result<u64> {
        self.next_id += 1;
        let mut message = json!({ "id": self.next_id, "method": method, "params": params });
        if let Some(s) = session {
            message["sessionId"] = json!(s);
        }
        let mut bytes = serde_json::to_vec(&message).unwrap();
        bytes.push(0);
        self.to_browser.write_all(&bytes)?;
        self.to_browser.flush()?;
        Ok(self.next_id)
    }

    fn send(&mut self, method: &str, params: Value, session: Option<&str>) -> Result<Value, Value> {
        let id = self
            .write(method, params, session)
            .unwrap_or_else(|e| panic!("{method}: the browser's pipe: {e}"));
        // Events and other replies in between are skipped.
        loop {
            let reply = match self.from_browser.recv_timeout(REPLY_TIMEOUT) {
                Ok(reply) => reply,
                Err(RecvTimeoutError::Timeout) => panic!("{method}: no reply in {REPLY_TIMEOUT:?}"),
                Err(RecvTimeoutError::Disconnected) => panic!("{method}: the browser exited"),
            };
            if reply["id"] == json!(id) {
                return match reply.get("error") {
                    Some(e) => Err(e.clone()),
                    None => Ok(reply["result"].clone()),
                };
            }
        }
    }

    /// Loads `url` in the page (returns once the navigation started; wait for the page's own
    /// readiness after).
    pub fn navigate(&mut self, url: &str) {
        let reply = self.call("Page.navigate", json!({ "url": url }));
        assert!(reply.get("errorText").is_none(), "{url}: {reply}");
    }

    /// Evaluates `js` in the page; its value comes back through JSON (objects included). `None`
    /// when the page threw or had no context to run it in (e.g. while navigating).
    pub fn try_eval(&mut self, js: &str) -> Option<Value> {
        let reply = self
            .try_call(
                "Runtime.evaluate",
                json!({ "expression": format!("JSON.stringify({js})"), "returnByValue": true }),
            )
            .ok()?;
        if reply.get("exceptionDetails").is_some() {
            return None;
        }
        match &reply["result"]["value"] {
            Value::String(text) => Some(serde_json::from_str(text).unwrap()),
            _ => Some(Value::Null),
        }
    }

    /// [`Self::try_eval`], failing the test when the page threw.
    pub fn eval(&mut self, js: &str) -> Value {
        self.try_eval(js)
            .unwrap_or_else(|| panic!("{js}: the page threw or had no context"))
    }

    /// A PNG screenshot of the page's CSS-pixel box `(x, y, width, height)` at scale 1.
    pub fn screenshot_png(&mut self, (x, y, width, height): (f64, f64, f64, f64)) -> Vec<u8> {
        let reply = self.call(
            "Page.captureScreenshot",
            json!({
                "format": "png",
                "clip": { "x": x, "y": y, "width": width, "height": height, "scale": 1.0 },
                "captureBeyondViewport": true,
            }),
        );
        base64::engine::general_purpose::STANDARD
            .decode(reply["data"].as_str().unwrap())
            .unwrap()
    }

    /// Dispatches a left-button mouse event: `kind` is `mouseMoved`, `mousePressed` or
    /// `mouseReleased`; the button is held during moves when `held`.
    pub fn mouse(&mut self, kind: &str, (x, y): (f64, f64), held: bool) {
        self.call(
            "Input.dispatchMouseEvent",
            json!({
                "type": kind,
                "x": x,
                "y": y,
                "button": "left",
                "buttons": if held { 1 } else { 0 },
                "clickCount": 1,
            }),
        );
    }

    /// A left click at `point`: move there, press, release.
    pub fn click(&mut self, point: (f64, f64)) {
        self.mouse("mouseMoved", point, false);
        self.mouse("mousePressed", point, true);
        self.mouse("mouseReleased", point, false);
    }
}

impl Drop for Chromium {
    fn drop(&mut self) {
        // Ask politely, then make sure: no browser outlives its test.
        // (Nothing here may panic: this runs while a failed test unwinds too.)
        if self.write("Browser.close", json!({}), None).is_ok() {
            for _ in 0..100 {
                if let Ok(Some(_)) = self.child.try_wait() {
                    return;
                }
                std::thread::sleep(Duration::from_millis(50));
            }
        }
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}
