//! `evogs demo --quick`, as the README runs it: both methods reach a PSNR floor that an untrained
//! model does not (the embedded scene's untrained render scores about 10 dB), and EvoGS is not
//! worse than the baseline beyond run-to-run noise. Training is deterministic for the seed, so
//! the margin below covers changes of the code rather than of the machine. The run is shared with
//! `demo_cli` (`support::quick_demo`).

use crate::support;

/// PSNR floor for both methods after the quick budget (measured: baseline 22.3, EvoGS 24.0 dB).
const FLOOR_DB: f64 = 20.0;
/// How far EvoGS may fall below the baseline before the test fails.
const NOISE_DB: f64 = 0.5;

#[test]
fn quick_demo_meets_the_floor_and_evogs_is_not_worse() {
    let (text, _) = support::quick_demo();
    let psnr = |method: &str| -> f64 {
        let row = text
            .lines()
            .find(|l| l.starts_with(&format!("| {method} ")))
            .unwrap_or_else(|| panic!("no {method} row in\n{text}"));
        row.split('|').nth(2).unwrap().trim().parse().unwrap()
    };
    let (baseline, evo) = (psnr("baseline"), psnr("evogs"));
    assert!(baseline > FLOOR_DB, "baseline {baseline} dB\n{text}");
    assert!(evo > FLOOR_DB, "EvoGS {evo} dB\n{text}");
    assert!(
        evo >= baseline - NOISE_DB,
        "EvoGS {evo} dB vs baseline {baseline} dB\n{text}"
    );
}
