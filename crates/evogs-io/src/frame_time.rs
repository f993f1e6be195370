//! Times for frames whose dataset does not store one (COLMAP without a `times.json`, and
//! nerfstudio frames without a
//! `time` key): from the order of the image names, from a number in each name, or none.
//!
//! What it is: the rule ([`TimeFrom`]) and the mapping from image names to times in [0, 1]
//! ([`times_from_names`]). What it is not: a reader; the loaders call it with their names.
//!
//! Accepted names for [`TimeFrom::Name`] (the number is read from the name relative to the
//! images folder; the extension is ignored):
//!
//! | name | number | why |
//! |---|---|---|
//! | `frame_000120.png`, `frame-12.jpg`, `Frame.7.png`, `frame3.png` | 120, 12, 7, 3 | `frame` (any case), then `_`, `-`, `.` or nothing, then digits |
//! | `cam03/frame_000120.png`, `frame000120_cam03.jpg` | 120 | the `frame` number wins over other digits: multi-camera captures share frame numbers, so their images share times |
//! | `000120.png`, `img_0042.jpg`, `r_005.png`, `cam03/000120.png` | 120, 42, 5, 120 | otherwise the last run of digits in the file's stem (not its folders) |
//! | `still.png` | — | an error naming the image: no number |
//!
//! Put `frame` before the frame number when a camera number follows it (`0120_cam03.png` reads
//! 3; `frame0120_cam03.png` reads 120).

use serde::{Deserialize, Serialize};
use splat_core::one_word::{OneWord, unknown_message};

/// Where a frame's time comes from when the dataset stores none, spelled `order`, `name` or
/// `none` on the command line and in files.
#[derive(strum::Display, strum::EnumString, strum::IntoStaticStr, strum::VariantNames)]
#[strum(serialize_all = "lowercase", parse_err_ty = String, parse_err_fn = unknown_message::<Self>)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum TimeFrom {
    /// The rank of the image name among all the dataset's image names, sorted: `i / (N − 1)`
    /// (first 0, last 1). 4DGaussians' COLMAP loader uses the read order over `N` instead, so
    /// its last frame sits at `(N − 1) / N`.
    #[default]
    Order,
    /// A number in the image name (see the [module docs](self)): `(n − n_min) / (n_max − n_min)`
    /// over the distinct numbers. Deformable-3D-Gaussians reads `int(name) / (N − 1)`, the same
    /// for names `0 … N−1`.
    Name,
    /// Time 0 for every frame: a static scene.
    None,
}

impl TimeFrom {
    /// Every rule.
    pub const ALL: [TimeFrom; 3] = [TimeFrom::Order, TimeFrom::Name, TimeFrom::None];

    /// The rule's name on the command line and in files.
    pub fn name(self) -> &'static str {
        self.into()
    }

    /// One line of help.
    pub fn help(self) -> &'static str {
        match self {
            Self::Order => "rank of the image name among the sorted names (a video's frames)",
            Self::Name => {
                "a number in the image name: after `frame` if present, else the last digits \
                 (multi-camera captures share frame numbers)"
            }
            Self::None => "time 0 for every image (a static scene)",
        }
    }
}

/// [`TimeFrom`]'s `from_str` error: "unknown time rule `x`; expected order, name or none".
impl OneWord for TimeFrom {
    const FIELD: &'static str = "time-from";
    const NOUN: &'static str = "time rule";
}

/// The frame number in an image name (see the [module docs](self)), `None` when it has none or
/// the number does not fit in a `u64`.
pub fn frame_number(name: &str) -> Option<u64> {
    let lower = name.to_ascii_lowercase();
    // `frame` followed by an optional separator and digits, anywhere in the relative path.
    let mut search = 0;
    while let Some(found) = lower[search..].find("frame") {
        let after = &lower[search + found + "frame".len()..];
        let after = after.strip_prefix(['_', '-', '.']).unwrap_or(after);
        let digits: String = after.chars().take_while(char::is_ascii_digit).collect();
        if !digits.is_empty() {
            return digits.parse().ok();
        }
        search += found + 1;
    }
    // Otherwise the last run of digits in the stem.
    let file = name.rsplit(['/', '\\']).next().unwrap_or(name);
    let stem = match file.rfind('.') {
        Some(dot) if dot > 0 => &file[..dot],
        _ => file,
    };
    let end = stem.rfind(|c: char| c.is_ascii_digit())? + 1;
    let start = stem[..end]
        .rfind(|c: char| !c.is_ascii_digit())
        .map_or(0, |i| i + 1);
    stem[start..end].parse().ok()
}

/// Times in [0, 1] for images named `names` (relative to the images folder), in the same order.
/// `Err((index, problem))` names the first image without a usable number for [`TimeFrom::Name`].
pub fn times_from_names(names: &[&str], from: TimeFrom) -> Result<Vec<f32>, (usize, String)> {
    match from {
        TimeFrom::None => Ok(vec![0.0; names.len()]),
        TimeFrom::Order => {
            let mut order: Vec<usize> = (0..names.len()).collect();
            order.sort_by(|&a, &b| names[a].cmp(names[b]));
            let mut times = vec![0.0; names.len()];
            let last = names.len().saturating_sub(1).max(1) as f64;
            for (rank, &index) in order.iter().enumerate() {
                times[index] = (rank as f64 / last) as f32;
            }
            Ok(times)
        }
        TimeFrom::Name => {
            let numbers = names
                .iter()
                .enumerate()
                .map(|(i, name)| {
                    frame_number(name).ok_or_else(|| {
                        (
                            i,
                            format!(
                                "`{name}` has no frame number for --time-from name (expected \
                                 `frame<N>` or digits in the file name, e.g. frame_0012.png or \
                                 0012.png)"
                            ),
                        )
                    })
                })
                .collect::<Result<Vec<u64>, _>>()?;
            let (Some(&lo), Some(&hi)) = (numbers.iter().min(), numbers.iter().max()) else {
                return Ok(Vec::new());
            };
            let span = (hi - lo).max(1) as f64;
            Ok(numbers
                .iter()
                .map(|&n| ((n - lo) as f64 / span) as f32)
                .collect())
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn messages_list_every_spelling() {
        assert_eq!(
            "Order".parse::<TimeFrom>().unwrap_err(),
            "unknown time rule `Order`; expected order, name or none"
        );
    }

    #[test]
    fn spellings_round_trip() {
        for rule in TimeFrom::ALL {
            assert_eq!(rule.to_string().parse::<TimeFrom>(), Ok(rule));
            assert_eq!(rule.name(), rule.to_string());
        }
    }

    #[test]
    fn frame_numbers_follow_the_documented_patterns() {
        let cases = [
            ("frame_000120.png", Some(120)),
            ("frame-12.jpg", Some(12)),
            ("Frame.7.png", Some(7)),
            ("frame3.png", Some(3)),
            ("cam03/frame_000120.png", Some(120)),
            ("frame000120_cam03.jpg", Some(120)),
            ("framed/0042.png", Some(42)),
            ("000120.png", Some(120)),
            ("img_0042.jpg", Some(42)),
            ("r_005.png", Some(5)),
            ("cam03/000120.png", Some(120)),
            ("0120_cam03.png", Some(3)),
            ("cam03/still.png", None),
            ("still.png", None),
            (".png", None),
            ("99999999999999999999999.png", None),
        ];
        for (name, want) in cases {
            assert_eq!(frame_number(name), want, "{name}");
        }
    }

    #[test]
    fn order_spans_zero_to_one_by_sorted_name() {
        let names = ["b.png", "a.png", "c.png"];
        assert_eq!(
            times_from_names(&names, TimeFrom::Order).unwrap(),
            vec![0.5, 0.0, 1.0]
        );
        assert_eq!(
            times_from_names(&["only.png"], TimeFrom::Order).unwrap(),
            vec![0.0]
        );
        assert!(times_from_names(&[], TimeFrom::Order).unwrap().is_empty());
    }

    #[test]
    fn name_times_share_frames_across_cameras_and_span_the_numbers() {
        let names = [
            "cam0/frame_0010.png",
            "cam1/frame_0010.png",
            "cam0/frame_0012.png",
            "cam1/frame_0014.png",
        ];
        assert_eq!(
            times_from_names(&names, TimeFrom::Name).unwrap(),
            vec![0.0, 0.0, 0.5, 1.0]
        );
        // One distinct number: time 0, no division by zero.
        assert_eq!(
            times_from_names(&["7.png", "x7.png"], TimeFrom::Name).unwrap(),
            vec![0.0, 0.0]
        );
        let (index, problem) =
            times_from_names(&["1.png", "sunset.png"], TimeFrom::Name).unwrap_err();
        assert_eq!(index, 1);
        assert!(problem.contains("`sunset.png`") && problem.contains("frame number"));
        assert_eq!(
            times_from_names(&["q.png"], TimeFrom::None).unwrap(),
            vec![0.0]
        );
    }

    #[test]
    fn names_round_trip_through_from_str() {
        for t in TimeFrom::ALL {
            assert_eq!(t.name().parse::<TimeFrom>().unwrap(), t);
        }
        assert!("date".parse::<TimeFrom>().unwrap_err().contains("order"));
    }
}
