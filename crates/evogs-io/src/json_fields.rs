//! Typed access to JSON fields with errors that name the file and the field path.

use std::path::Path;

use serde_json::{Map, Value};

use crate::IoError;

/// Reads and parses a JSON file.
pub(crate) fn load_json(path: &Path) -> Result<Value, IoError> {
    let bytes = std::fs::read(path).map_err(|e| IoError::io(path, e))?;
    serde_json::from_slice(&bytes).map_err(|cause| IoError::Json {
        path: path.to_path_buf(),
        cause,
    })
}

/// A JSON object, the file it came from and its field path prefix (`frames[3].`).
pub(crate) struct Fields<'a> {
    path: &'a Path,
    prefix: String,
    object: &'a Map<String, Value>,
}

fn kind_of(value: &Value) -> &'static str {
    match value {
        Value::Null => "null",
        Value::Bool(_) => "a boolean",
        Value::Number(_) => "a number",
        Value::String(_) => "a string",
        Value::Array(_) => "an array",
        Value::Object(_) => "an object",
    }
}

impl<'a> Fields<'a> {
    /// `value` as an object; `name` is its field path (empty for the document root).
    pub fn object(path: &'a Path, value: &'a Value, name: &str) -> Result<Self, IoError> {
        match value {
            Value::Object(object) => Ok(Self {
                path,
                prefix: if name.is_empty() {
                    String::new()
                } else {
                    format!("{name}.")
                },
                object,
            }),
            other => Err(IoError::field(
                path,
                if name.is_empty() { "(root)" } else { name },
                format!("expected an object, found {}", kind_of(other)),
            )),
        }
    }

    /// The full field path of `key`.
    pub fn name(&self, key: &str) -> String {
        format!("{}{key}", self.prefix)
    }

    /// An error about `key`.
    pub fn error(&self, key: &str, problem: impl Into<String>) -> IoError {
        IoError::field(self.path, self.name(key), problem)
    }

    /// The value of `key`, `None` when absent or null.
    pub fn optional(&self, key: &str) -> Option<&'a Value> {
        self.object.get(key).filter(|v| !v.is_null())
    }

    /// The value of `key`, an error when absent or null.
    pub fn required(&self, key: &str) -> Result<&'a Value, IoError> {
        self.optional(key).ok_or_else(|| self.error(key, "missing"))
    }

    fn as_number(&self, key: &str, value: &Value) -> Result<f64, IoError> {
        value
            .as_f64()
            .filter(|v| v.is_finite())
            .ok_or_else(|| self.error(key, format!("expected a number, found {}", kind_of(value))))
    }

    /// A required finite number.
    pub fn number(&self, key: &str) -> Result<f64, IoError> {
        self.as_number(key, self.required(key)?)
    }

    /// An optional finite number.
    pub fn optional_number(&self, key: &str) -> Result<Option<f64>, IoError> {
        self.optional(key)
            .map(|v| self.as_number(key, v))
            .transpose()
    }

    /// A required string.
    pub fn string(&self, key: &str) -> Result<&'a str, IoError> {
        let value = self.required(key)?;
        value
            .as_str()
            .ok_or_else(|| self.error(key, format!("expected a string, found {}", kind_of(value))))
    }

    /// A required array.
    pub fn array(&self, key: &str) -> Result<&'a Vec<Value>, IoError> {
        let value = self.required(key)?;
        value
            .as_array()
            .ok_or_else(|| self.error(key, format!("expected an array, found {}", kind_of(value))))
    }

    /// An array of finite numbers whose length lies in `lengths`, from `value` (the field `key`).
    fn numbers_of(
        &self,
        key: &str,
        value: &Value,
        lengths: std::ops::RangeInclusive<usize>,
    ) -> Result<Vec<f64>, IoError> {
        let items = value.as_array().ok_or_else(|| {
            self.error(
                key,
                format!("expected an array of numbers, found {}", kind_of(value)),
            )
        })?;
        if !lengths.contains(&items.len()) {
            let want = if lengths.start() == lengths.end() {
                format!("{}", lengths.start())
            } else {
                format!("{} to {}", lengths.start(), lengths.end())
            };
            return Err(self.error(
                key,
                format!("expected {want} numbers, found {}", items.len()),
            ));
        }
        items
            .iter()
            .enumerate()
            .map(|(i, v)| self.as_number(&format!("{key}[{i}]"), v))
            .collect()
    }

    /// A required array of finite numbers with a length in `lengths`.
    pub fn numbers(
        &self,
        key: &str,
        lengths: std::ops::RangeInclusive<usize>,
    ) -> Result<Vec<f64>, IoError> {
        self.numbers_of(key, self.required(key)?, lengths)
    }

    /// An optional array of finite numbers with a length in `lengths`.
    pub fn optional_numbers(
        &self,
        key: &str,
        lengths: std::ops::RangeInclusive<usize>,
    ) -> Result<Option<Vec<f64>>, IoError> {
        self.optional(key)
            .map(|v| self.numbers_of(key, v, lengths))
            .transpose()
    }

    /// A required matrix of finite numbers, `rows` rows (a range) of `cols` numbers each.
    pub fn matrix(
        &self,
        key: &str,
        rows: std::ops::RangeInclusive<usize>,
        cols: usize,
    ) -> Result<Vec<Vec<f64>>, IoError> {
        let value = self.required(key)?;
        let items = value.as_array().ok_or_else(|| {
            self.error(
                key,
                format!("expected an array of rows, found {}", kind_of(value)),
            )
        })?;
        if !rows.contains(&items.len()) {
            return Err(self.error(
                key,
                format!(
                    "expected {} to {} rows, found {}",
                    rows.start(),
                    rows.end(),
                    items.len()
                ),
            ));
        }
        items
            .iter()
            .enumerate()
            .map(|(i, row)| self.numbers_of(&format!("{key}[{i}]"), row, cols..=cols))
            .collect()
    }
}

/// How far `rows` (3×3, row-major) is from a proper rotation: the largest entry of `R Rᵀ − I`,
/// or infinity when the determinant is not positive.
pub fn rotation_error(rows: &[[f64; 3]; 3]) -> f64 {
    let dot = |a: &[f64; 3], b: &[f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let mut worst: f64 = 0.0;
    for i in 0..3 {
        for j in 0..3 {
            let want = if i == j { 1.0 } else { 0.0 };
            worst = worst.max((dot(&rows[i], &rows[j]) - want).abs());
        }
    }
    let [a, b, c] = rows;
    let det = a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0])
        + a[2] * (b[0] * c[1] - b[1] * c[0]);
    if det > 0.0 { worst } else { f64::INFINITY }
}

/// Rotations whose `R Rᵀ` deviates from `I` by more than this are rejected.
pub const ROTATION_TOLERANCE: f64 = 1e-3;
