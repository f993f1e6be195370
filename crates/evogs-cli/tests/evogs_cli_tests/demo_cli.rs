//! `evogs demo`: both methods are trained, evaluated and swept, the table names both with finite
//! metrics, and only EvoGS holds an evolution buffer. Checked on the `--quick` run that
//! `demo_quick` scores (`support::quick_demo`, run once), rather than on a run of its own.

use crate::support;

#[test]
fn demo_compares_both_methods_and_writes_renders() {
    let (text, out) = support::quick_demo();
    let rows: Vec<Vec<&str>> = text
        .lines()
        .filter(|l| l.starts_with("| baseline") || l.starts_with("| evogs"))
        .map(|l| {
            l.split('|')
                .map(str::trim)
                .filter(|c| !c.is_empty())
                .collect()
        })
        .collect();
    assert_eq!(rows.len(), 2, "{text}");
    for row in &rows {
        assert_eq!(row.len(), 8, "{row:?}");
        for cell in &row[1..] {
            let v: f64 = cell.parse().unwrap_or_else(|_| panic!("{cell} in {row:?}"));
            assert!(v.is_finite() && v >= 0.0, "{row:?}");
        }
    }
    assert_eq!(rows[0][7], "0.0", "the baseline keeps no buffer");
    assert!(
        rows[1][7].parse::<f64>().unwrap() > 0.0,
        "EvoGS keeps a buffer"
    );
    for m in ["baseline", "evogs"] {
        assert!(out.join(m).join("sweep/strip.png").is_file(), "{m} strip");
        assert!(
            out.join(m).join("renders/test/0000.png").is_file(),
            "{m} renders"
        );
    }
    // It ends by naming its pictures and the command that shows them.
    let o = out.display();
    assert!(
        text.contains(&format!("`evogs view {o}/evogs {o}/baseline`"))
            && text.contains(&format!("`{o}/evogs/sweep/`")),
        "{text}"
    );
    assert_eq!(
        std::fs::read_to_string(out.join("demo.md")).unwrap().trim(),
        text.lines()
            .take_while(|l| !l.starts_with("wrote"))
            .collect::<Vec<_>>()
            .join("\n")
            .trim()
    );
}
