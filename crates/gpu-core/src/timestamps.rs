//! GPU timestamps of labelled spans of device work, where the adapter has them (issue W): the
//! device's own time for a phase, which the host's timers cannot split (work submitted without a
//! wait is charged to whoever waits next).
//!
//! A span is two timestamps written into the caller's encoder ([`Timestamps::begin`],
//! [`Timestamps::end`]; wgpu's `TIMESTAMP_QUERY_INSIDE_ENCODERS`). Spans are read by the next
//! [`read_back`](crate::buffers::read_back) on the context, which resolves every span ended
//! since the last one into its own staging copy (16 bytes a span, counted as traffic like any
//! read-back) and adds each span's duration to its label's total ([`Timestamps::totals`]). So
//! the spans cost no wait of their own; the contract is that a span's encoder is submitted
//! before the read-back that collects it (every caller here submits in order). A span whose
//! timestamps come back unwritten or reversed (an encoder dropped unsubmitted) is counted as
//! missed, not timed; so is one begun while [`MAX_SPANS`] spans wait to be collected.
//!
//! Durations are device time between the two writes, converted with the queue's timestamp
//! period; a driver may order work between them differently from the recording (spans of
//! one encoder are sequential in practice). What it is not: a profiler of host time (the
//! trainer's `PhaseTimes` is), nor per-dispatch timing.

use std::collections::BTreeMap;
use std::sync::Mutex;

/// Spans that may wait to be collected at once.
pub const MAX_SPANS: u32 = 256;

/// A span's total: device nanoseconds and the spans that made it.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SpanTotal {
    /// Device time, nanoseconds.
    pub nanos: f64,
    /// Spans added.
    pub count: u64,
}

/// A span begun by [`Timestamps::begin`], to hand to [`Timestamps::end`] (`None` inside: not
/// timed, the set being full).
#[must_use = "end the span in the same encoder"]
#[derive(Debug)]
pub struct Span(Option<(u64, u32)>);

#[derive(Debug, Default)]
struct State {
    /// Collections taken so far: a span ends only in the generation it began in.
    generation: u64,
    /// Label of each pair of queries written since the last collection, by pair index.
    pending: Vec<&'static str>,
    /// Whether each pending pair's end was written.
    ended: Vec<bool>,
    totals: BTreeMap<&'static str, SpanTotal>,
    missed: u64,
}

/// The context's timestamp queries and the totals they have given.
#[derive(Debug)]
pub struct Timestamps {
    set: wgpu::QuerySet,
    resolve: wgpu::Buffer,
    period_ns: f64,
    state: Mutex<State>,
}

/// The spans taken for one read-back: their labels, and whether each was ended.
pub(crate) struct Collection {
    labels: Vec<(&'static str, bool)>,
}

impl Collection {
    /// Bytes the spans' timestamps take (two u64 each).
    pub(crate) fn bytes(&self) -> u64 {
        16 * self.labels.len() as u64
    }
}

impl Timestamps {
    /// The queries of `device` (which must have `TIMESTAMP_QUERY` and
    /// `TIMESTAMP_QUERY_INSIDE_ENCODERS`), timed with `queue`'s period.
    pub(crate) fn new(device: &wgpu::Device, queue: &wgpu::Queue) -> Self {
        Self {
            set: device.create_query_set(&wgpu::QuerySetDescriptor {
                label: Some("timestamps"),
                ty: wgpu::QueryType::Timestamp,
                count: 2 * MAX_SPANS,
            }),
            resolve: device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("timestamps resolved"),
                size: 16 * u64::from(MAX_SPANS),
                usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            }),
            period_ns: f64::from(queue.get_timestamp_period()),
            state: Mutex::new(State::default()),
        }
    }

    fn state(&self) -> std::sync::MutexGuard<'_, State> {
        self.state.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Begins a span labelled `label` in `encoder` (a timestamp written there).
    pub fn begin(&self, encoder: &mut wgpu::CommandEncoder, label: &'static str) -> Span {
        let mut state = self.state();
        let index = state.pending.len() as u32;
        if index >= MAX_SPANS {
            state.missed += 1;
            return Span(None);
        }
        state.pending.push(label);
        state.ended.push(false);
        encoder.write_timestamp(&self.set, 2 * index);
        Span(Some((state.generation, index)))
    }

    /// Ends `span` in `encoder` (the one it began in). A span collected before its end (a
    /// read-back between the two) is not timed.
    pub fn end(&self, encoder: &mut wgpu::CommandEncoder, span: Span) {
        if let Some((generation, index)) = span.0 {
            let mut state = self.state();
            if generation == state.generation {
                state.ended[index as usize] = true;
                encoder.write_timestamp(&self.set, 2 * index + 1);
            }
        }
    }

    /// Takes every pending span for a read-back (`None` when none is pending); the read-back
    /// records them with [`record`](Self::record).
    pub(crate) fn take(&self) -> Option<Collection> {
        let mut state = self.state();
        if state.pending.is_empty() {
            return None;
        }
        state.generation += 1;
        let ended = std::mem::take(&mut state.ended);
        let labels = state.pending.drain(..).zip(ended).collect();
        Some(Collection { labels })
    }

    /// Records the resolution of `collection`'s spans into `encoder` and their copy into
    /// `staging` at `offset`.
    pub(crate) fn record(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        collection: &Collection,
        staging: &wgpu::Buffer,
        offset: u64,
    ) {
        let n = collection.labels.len() as u32;
        encoder.resolve_query_set(&self.set, 0..2 * n, &self.resolve, 0);
        encoder.copy_buffer_to_buffer(&self.resolve, 0, staging, offset, collection.bytes());
    }

    /// Adds a collection's spans from the read-back `bytes` (two u64 timestamps each).
    pub(crate) fn add(&self, collection: Collection, bytes: &[u8]) {
        let stamps: Vec<u64> = bytemuck::pod_collect_to_vec(bytes);
        let mut state = self.state();
        for ((label, ended), pair) in collection.labels.into_iter().zip(stamps.chunks_exact(2)) {
            let (begin, end) = (pair[0], pair[1]);
            if !ended || begin == 0 || end < begin {
                state.missed += 1;
                continue;
            }
            let total = state.totals.entry(label).or_default();
            total.nanos += (end - begin) as f64 * self.period_ns;
            total.count += 1;
        }
    }

    /// Every label's total since the context was made, and the spans missed (not timed).
    pub fn totals(&self) -> (BTreeMap<&'static str, SpanTotal>, u64) {
        let state = self.state();
        (state.totals.clone(), state.missed)
    }
}

#[cfg(test)]
mod tests {
    use crate::GpuContext;
    use crate::buffers::{read_back, storage};

    /// Spans are collected by the next read-back, by label, without changing what the traffic
    /// counts; a span collected before its end, and one begun while the set is full, are
    /// missed, not timed. Lavapipe (CI) writes timestamps inside encoders, so a software adapter
    /// without them fails; a hardware one without them gives no spans.
    #[test]
    fn spans_are_collected_by_the_next_read_back() {
        let ctx = GpuContext::new().expect("an adapter (CI installs lavapipe)");
        let Some(t) = &ctx.timestamps else {
            assert!(
                ctx.adapter().hardware,
                "lavapipe writes timestamps inside encoders"
            );
            let mut enc = ctx.device.create_command_encoder(&Default::default());
            assert!(ctx.span_begin(&mut enc, "none").is_none());
            return;
        };
        let buf = storage(&ctx, "work", 1 << 20).unwrap();
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        for label in ["clear", "clear", "copy"] {
            let span = ctx.span_begin(&mut enc, label);
            enc.clear_buffer(&buf, 0, None);
            ctx.span_end(&mut enc, span);
        }
        let before = ctx.traffic();
        read_back(&ctx, enc, &[(&buf, 0, 64)]).unwrap();
        let moved = ctx.traffic().since(&before);
        assert_eq!(
            (moved.bytes_down, moved.waits),
            (64, 1),
            "spans are not traffic"
        );
        let (totals, missed) = t.totals();
        assert_eq!(missed, 0);
        assert_eq!(
            totals.keys().copied().collect::<Vec<_>>(),
            ["clear", "copy"]
        );
        assert_eq!((totals["clear"].count, totals["copy"].count), (2, 1));
        assert!(
            totals
                .values()
                .all(|s| s.nanos >= 0.0 && s.nanos.is_finite())
        );

        // Begun, collected by a read-back in between, then ended: missed.
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        let open = t.begin(&mut enc, "open");
        read_back(&ctx, enc, &[(&buf, 0, 4)]).unwrap();
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        t.end(&mut enc, open);
        read_back(&ctx, enc, &[(&buf, 0, 4)]).unwrap();
        let (totals, missed) = t.totals();
        assert_eq!((missed, totals.contains_key("open")), (1, false));

        // A full set: the span past it is not timed.
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        for _ in 0..super::MAX_SPANS + 1 {
            let span = t.begin(&mut enc, "many");
            t.end(&mut enc, span);
        }
        read_back(&ctx, enc, &[(&buf, 0, 4)]).unwrap();
        let (totals, missed) = t.totals();
        assert_eq!(
            (totals["many"].count, missed),
            (u64::from(super::MAX_SPANS), 2)
        );
    }
}
