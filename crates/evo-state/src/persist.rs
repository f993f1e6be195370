//! Saving and loading the whole state as safetensors, bit-exact. Format `evo-state/2`. Tensors:
//! `times` (F32 `[T]`), `valid` (U8 `[T]`), `psi` (F32 `[P]`), `psi_input_ema` (F64 `[D+2]`) and
//! `psi_input_weight` (F64 `[1]`) (the running RMS of Ψ's inputs, [`crate::norm`]), with
//! evolution on `memory.KKKKK` (the residual memory `M[k]`, F32 or F16 `[N, D]`) per frame, and
//! with a buffer `buffer.KKKKK` (F32 or F16 `[N, D]`) per frame. The configuration and counters
//! are string metadata; floats are written in Rust's shortest round-trip form, so they load
//! bit-exact. The file is written to a temporary file in the same directory and renamed.
//!
//! Files of the earlier format `evo-state/1` (one f32 `memory` `[N, D]` per Gaussian, overwritten
//! by whichever frame trained last, and Ψ inputs divided by the scene extent) still load: their
//! per-frame memory is zero (the old memory belongs to no frame) and their Ψ input normaliser is
//! the fixed extent scaling they were trained with ([`crate::norm::InputNorm::legacy`]).

use std::collections::{BTreeMap, HashMap};
use std::io::Write;
use std::path::Path;

use half::f16;
use safetensors::tensor::{Dtype, SafeTensors, TensorView};

use crate::buffer::{Block, StateBuffer};
use crate::config::{EvoConfig, Gain, HistoryMode, Layout, ParseError, Storage};
use crate::error::EvoError;
use crate::frames::Frames;
use crate::gain::GainNet;
use crate::norm::InputNorm;
use crate::state::EvoState;

const FORMAT: &str = "evo-state/2";
/// The format before per-frame memory and running-RMS input normalisation.
const FORMAT_V1: &str = "evo-state/1";

fn buffer_name(k: usize) -> String {
    format!("buffer.{k:05}")
}

fn memory_name(k: usize) -> String {
    format!("memory.{k:05}")
}

fn blocks_views(
    buffer: &StateBuffer,
    name: fn(usize) -> String,
    rows: usize,
    dim: usize,
) -> Vec<(String, Dtype, Vec<usize>, &[u8])> {
    buffer
        .blocks
        .iter()
        .enumerate()
        .map(|(k, block)| {
            let (dtype, bytes): (Dtype, &[u8]) = match block {
                Block::F32(v) => (Dtype::F32, bytemuck::cast_slice(v)),
                Block::F16(v) => (Dtype::F16, bytemuck::cast_slice(v)),
            };
            (name(k), dtype, vec![rows, dim], bytes)
        })
        .collect()
}

fn f32_bytes(v: &[f32]) -> &[u8] {
    bytemuck::cast_slice(v)
}

impl EvoState {
    /// Saves the whole state to `path` (safetensors).
    pub fn save(&self, path: &Path) -> Result<(), EvoError> {
        let io = |source| EvoError::Io {
            path: path.to_path_buf(),
            source,
        };
        let c = &self.config;
        let mut meta: HashMap<String, String> = HashMap::new();
        let mut put = |k: &str, v: String| {
            meta.insert(k.to_string(), v);
        };
        put("format", FORMAT.into());
        put("layout_bits", c.layout.bits().to_string());
        put("storage", c.storage.to_string());
        put("beta", c.beta.to_string());
        put("max_gap", c.max_gap.to_string());
        put("motion_floor", c.motion_floor.to_string());
        put("extent", c.extent.to_string());
        put("evolution", c.evolution.to_string());
        put(
            "gain",
            match c.gain {
                Gain::Learned => "learned".into(),
                Gain::Fixed(k) => format!("fixed:{k}"),
            },
        );
        put("history", c.history.to_string());
        put("lambda_sup", c.lambda_sup.to_string());
        put("lambda_prior", c.lambda_prior.to_string());
        put("rows", self.rows.to_string());
        put("saturations", self.saturations.to_string());
        put("generation", self.generation.to_string());
        put("psi_seed", self.psi.mlp().config().seed.to_string());

        let dim = self.dim();
        let valid: Vec<u8> = self.valid.iter().map(|&v| v as u8).collect();
        let psi = self.psi.params();
        let norm_ema: &[u8] = bytemuck::cast_slice(&self.psi_norm.ema);
        let norm_weight = [self.psi_norm.weight];
        let view = |dtype, shape: Vec<usize>, data| {
            TensorView::new(dtype, shape, data).map_err(|e| EvoError::Format {
                path: path.to_path_buf(),
                field: "tensor".into(),
                problem: e.to_string(),
            })
        };
        let mut tensors: Vec<(String, TensorView<'_>)> = vec![
            (
                "times".into(),
                view(
                    Dtype::F32,
                    vec![self.frames.len()],
                    f32_bytes(self.frames.times()),
                )?,
            ),
            ("valid".into(), view(Dtype::U8, vec![valid.len()], &valid)?),
            (
                "psi".into(),
                view(Dtype::F32, vec![self.psi.params().len()], f32_bytes(&psi))?,
            ),
            (
                "psi_input_ema".into(),
                view(Dtype::F64, vec![self.psi_norm.ema.len()], norm_ema)?,
            ),
            (
                "psi_input_weight".into(),
                view(Dtype::F64, vec![1], bytemuck::cast_slice(&norm_weight))?,
            ),
        ];
        let blocks = [
            (&self.memory, memory_name as fn(usize) -> String),
            (&self.buffer, buffer_name),
        ];
        for (buffer, name) in blocks {
            if let Some(buffer) = buffer {
                for (n, dtype, shape, bytes) in blocks_views(buffer, name, self.rows, dim) {
                    tensors.push((n, view(dtype, shape, bytes)?));
                }
            }
        }
        let sorted = sorted_metadata_json(&meta);
        let mut bytes =
            safetensors::serialize(tensors, Some(meta)).map_err(|e| EvoError::Format {
                path: path.to_path_buf(),
                field: "safetensors".into(),
                problem: e.to_string(),
            })?;
        sort_metadata(&mut bytes, &sorted).map_err(|problem| EvoError::Format {
            path: path.to_path_buf(),
            field: "safetensors header".into(),
            problem,
        })?;
        let dir = path
            .parent()
            .filter(|p| !p.as_os_str().is_empty())
            .unwrap_or(Path::new("."));
        // The prefix of evogs-io's atomic writes, so that a run directory's clean-up after a
        // kill finds this file too.
        let mut tmp = tempfile::Builder::new()
            .prefix(".evogs-tmp-")
            .tempfile_in(dir)
            .map_err(io)?;
        // Through the plain file: the temporary file's own writer adds its random name to errors.
        tmp.as_file_mut().write_all(&bytes).map_err(io)?;
        tiny_nn::weights::set_output_mode(tmp.as_file(), path).map_err(io)?;
        tmp.as_file().sync_all().map_err(io)?;
        tmp.persist(path).map_err(|e| io(e.error))?;
        Ok(())
    }

    /// Loads a state saved by [`EvoState::save`]. Every problem names the file and the field.
    pub fn load(path: &Path) -> Result<Self, EvoError> {
        let bytes = std::fs::read(path).map_err(|source| EvoError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        let bad = |field: &str, problem: String| EvoError::Format {
            path: path.to_path_buf(),
            field: field.to_string(),
            problem,
        };
        let (_, header) =
            SafeTensors::read_metadata(&bytes).map_err(|e| bad("safetensors", e.to_string()))?;
        let tensors =
            SafeTensors::deserialize(&bytes).map_err(|e| bad("safetensors", e.to_string()))?;
        let empty = HashMap::new();
        let meta = header.metadata().as_ref().unwrap_or(&empty);
        let get = |k: &str| meta.get(k).ok_or_else(|| bad(k, "missing".into()));
        fn parse<T: std::str::FromStr>(
            s: &str,
            k: &str,
            bad: &dyn Fn(&str, String) -> EvoError,
        ) -> Result<T, EvoError> {
            s.parse().map_err(|_| bad(k, format!("cannot parse {s:?}")))
        }
        let num = |k: &str| -> Result<f32, EvoError> { parse(get(k)?, k, &bad) };
        let legacy = match get("format")?.as_str() {
            FORMAT => false,
            FORMAT_V1 => true,
            other => {
                return Err(bad(
                    "format",
                    format!("expected {FORMAT:?} (or the older {FORMAT_V1:?}), found {other:?}"),
                ));
            }
        };
        let bits: u8 = parse(get("layout_bits")?, "layout_bits", &bad)?;
        let layout = Layout::from_bits(bits)
            .ok_or_else(|| bad("layout_bits", format!("{bits} is not a layout")))?;
        let storage: Storage = get("storage")?
            .parse()
            .map_err(|e: tiny_nn::PrecisionParseError| bad("storage", e.to_string()))?;
        let gain = match get("gain")?.as_str() {
            "learned" => Gain::Learned,
            other => match other.strip_prefix("fixed:") {
                Some(k) => Gain::Fixed(parse(k, "gain", &bad)?),
                None => return Err(bad("gain", format!("unknown gain {other:?}"))),
            },
        };
        let history: HistoryMode = get("history")?
            .parse()
            .map_err(|e: ParseError| bad("history", e.to_string()))?;
        let config = EvoConfig {
            layout,
            storage,
            beta: num("beta")?,
            max_gap: parse(get("max_gap")?, "max_gap", &bad)?,
            motion_floor: num("motion_floor")?,
            extent: num("extent")?,
            evolution: parse(get("evolution")?, "evolution", &bad)?,
            gain,
            history,
            lambda_sup: num("lambda_sup")?,
            lambda_prior: num("lambda_prior")?,
        };
        config.validate().map_err(|e| bad(e.field, e.to_string()))?;
        let rows: usize = parse(get("rows")?, "rows", &bad)?;
        let saturations: u64 = parse(get("saturations")?, "saturations", &bad)?;
        let generation: u64 = parse(get("generation")?, "generation", &bad)?;
        let dim = config.dim();

        let tensor = |name: &str, dtype: Dtype, shape: &[usize]| -> Result<Vec<u8>, EvoError> {
            let t = tensors.tensor(name).map_err(|e| bad(name, e.to_string()))?;
            if t.dtype() != dtype {
                return Err(bad(
                    name,
                    format!("dtype {:?}, expected {dtype:?}", t.dtype()),
                ));
            }
            if t.shape() != shape {
                return Err(bad(
                    name,
                    format!("shape {:?}, expected {shape:?}", t.shape()),
                ));
            }
            Ok(t.data().to_vec())
        };
        let to_f32 = |b: Vec<u8>| -> Vec<f32> {
            b.chunks_exact(4)
                .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
                .collect()
        };
        let t_shape = tensors
            .tensor("times")
            .map_err(|e| bad("times", e.to_string()))?
            .shape()
            .to_vec();
        let [frame_count] = t_shape[..] else {
            return Err(bad("times", format!("shape {t_shape:?}, expected [T]")));
        };
        let frames = Frames::new(to_f32(tensor("times", Dtype::F32, &[frame_count])?))
            .map_err(|e| bad("times", e.to_string()))?;
        let valid_bytes = tensor("valid", Dtype::U8, &[frame_count])?;
        if let Some(b) = valid_bytes.iter().find(|&&b| b > 1) {
            return Err(bad("valid", format!("flag {b} is not 0 or 1")));
        }
        let valid = valid_bytes.iter().map(|&b| b == 1).collect();
        let psi_seed: u64 = parse(get("psi_seed")?, "psi_seed", &bad)?;
        let mut psi = GainNet::new(dim + 3, psi_seed).map_err(|e| bad("psi", e.to_string()))?;
        let psi_params = to_f32(tensor("psi", Dtype::F32, &[psi.param_count()])?);
        if psi_params.iter().any(|v| !v.is_finite()) {
            return Err(bad("psi", "non-finite parameter".into()));
        }
        psi.set_params(&psi_params)
            .map_err(|e| bad("psi", e.to_string()))?;
        let read_blocks = |name: fn(usize) -> String| -> Result<StateBuffer, EvoError> {
            let mut blocks = Vec::with_capacity(frame_count);
            for k in 0..frame_count {
                let name = name(k);
                let block = match storage {
                    Storage::F32 => {
                        let v = to_f32(tensor(&name, Dtype::F32, &[rows, dim])?);
                        if let Some(p) = v.iter().position(|x| !x.is_finite()) {
                            return Err(bad(
                                &name,
                                format!("non-finite value at Gaussian {}", p / dim.max(1)),
                            ));
                        }
                        Block::F32(v)
                    }
                    Storage::F16 => {
                        let b = tensor(&name, Dtype::F16, &[rows, dim])?;
                        let v: Vec<f16> = b
                            .chunks_exact(2)
                            .map(|c| f16::from_le_bytes([c[0], c[1]]))
                            .collect();
                        if let Some(p) = v.iter().position(|x| !x.is_finite()) {
                            return Err(bad(
                                &name,
                                format!("non-finite value at Gaussian {}", p / dim.max(1)),
                            ));
                        }
                        Block::F16(v)
                    }
                };
                blocks.push(block);
            }
            Ok(StateBuffer {
                storage,
                rows,
                dim,
                blocks,
            })
        };
        let memory = match (config.evolution, legacy) {
            (false, _) => None,
            // The old per-Gaussian memory belongs to no frame: start from zero memory.
            (true, true) => Some(StateBuffer::new(storage, frame_count, rows, dim)),
            (true, false) => Some(read_blocks(memory_name)?),
        };
        let buffer = if config.evolution && config.history == HistoryMode::Buffer {
            Some(read_blocks(buffer_name)?)
        } else {
            None
        };
        let psi_norm = if legacy {
            InputNorm::legacy(
                dim,
                config.layout.range(crate::config::Component::Position),
                config.extent as f64,
            )
        } else {
            let f64s = |b: Vec<u8>| -> Vec<f64> {
                b.chunks_exact(8)
                    .map(|c| f64::from_le_bytes(c.try_into().expect("8 bytes")))
                    .collect()
            };
            let ema = f64s(tensor("psi_input_ema", Dtype::F64, &[dim + 2])?);
            if ema.iter().any(|v| !(v.is_finite() && *v >= 0.0)) {
                return Err(bad(
                    "psi_input_ema",
                    "mean squares must be finite and >= 0".into(),
                ));
            }
            let weight = f64s(tensor("psi_input_weight", Dtype::F64, &[1])?)[0];
            if !(0.0..=1.0).contains(&weight) {
                return Err(bad(
                    "psi_input_weight",
                    format!("{weight} is outside [0, 1]"),
                ));
            }
            InputNorm { ema, weight }
        };
        Ok(Self {
            config,
            frames,
            rows,
            generation,
            buffer,
            valid,
            memory,
            psi,
            psi_norm,
            saturations,
        })
    }
}

/// The metadata object as safetensors writes it (compact JSON), with its keys sorted.
fn sorted_metadata_json(meta: &HashMap<String, String>) -> String {
    let sorted: BTreeMap<&str, &str> = meta.iter().map(|(k, v)| (k.as_str(), v.as_str())).collect();
    // A map of strings always serialises.
    serde_json::to_string(&sorted).unwrap_or_default()
}

/// Rewrites the header's metadata object of a serialised file with its keys sorted.
///
/// safetensors writes the metadata map in `HashMap` order, which differs from one map to the
/// next, so the same state gave different bytes (a resumed run's file differed from an
/// uninterrupted run's). The object is the header's first entry; `sorted` is the same pairs in
/// another order, so it has the same length and no tensor offset moves.
fn sort_metadata(bytes: &mut [u8], sorted: &str) -> Result<(), String> {
    const PREFIX: &[u8] = b"{\"__metadata__\":";
    let start = 8 + PREFIX.len();
    let end = start + sorted.len();
    let found = bytes.get(8..start) == Some(PREFIX)
        && bytes.get(end - 1) == Some(&b'}')
        && bytes.get(start) == Some(&b'{')
        && bytes
            .get(start..end)
            .is_some_and(|o| o.iter().filter(|&&b| b == b'}').count() == 1);
    if !found {
        return Err("metadata object not where safetensors writes it".into());
    }
    bytes[start..end].copy_from_slice(sorted.as_bytes());
    Ok(())
}
