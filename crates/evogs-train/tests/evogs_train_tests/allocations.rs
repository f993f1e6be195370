//! A warmed-up training iteration allocates nothing outside the networks: the rasterizer's
//! outputs and scratch, the loss, the deformed Gaussians, the gradient rows and the optimiser's
//! buffers are reused from one iteration to the next. Counted by a global allocator that counts
//! only on the threads of one rayon pool, so the other tests of this binary, running beside it,
//! are not counted.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

use crate::common;

use evogs_io::Split;
use evogs_train::data::load_split;
use evogs_train::{Method, Preset, TrainConfig, Trainer};

/// The system allocator, counting the allocations (and reallocations) made on the threads of
/// [`counted_pool`] while [`ACTIVE`] is set.
struct Counting;

thread_local! {
    /// Whether this thread is one of [`counted_pool`]'s.
    static COUNTED: Cell<bool> = const { Cell::new(false) };
}

/// Counting is on.
static ACTIVE: AtomicBool = AtomicBool::new(false);
/// Allocations (and reallocations) counted.
static ALLOCATIONS: AtomicU64 = AtomicU64::new(0);
/// Bytes they asked for.
static BYTES: AtomicU64 = AtomicU64::new(0);

fn note(size: usize) {
    // `try_with`: a thread's allocations after its thread-locals are gone are not counted (none
    // of the pool's threads is torn down while counting).
    if ACTIVE.load(Ordering::Relaxed) && COUNTED.try_with(Cell::get).unwrap_or(false) {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        BYTES.fetch_add(size as u64, Ordering::Relaxed);
    }
}

// SAFETY: every method forwards its arguments unchanged to `System`, which upholds
// `GlobalAlloc`'s contract; the counting beside it touches only atomics and a const-initialised
// thread-local `Cell<bool>` (no allocation, no destructor), so it cannot re-enter the allocator.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        note(layout.size());
        // SAFETY: the caller's `layout` is passed through (GlobalAlloc::alloc's contract).
        unsafe { System.alloc(layout) }
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        note(layout.size());
        // SAFETY: as `alloc`.
        unsafe { System.alloc_zeroed(layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        note(new_size);
        // SAFETY: `ptr` was allocated by `System` through this allocator with `layout`.
        unsafe { System.realloc(ptr, layout, new_size) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: `ptr` was allocated by `System` through this allocator with `layout`.
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

/// A pool of two threads whose allocations are counted (while [`ACTIVE`]).
fn counted_pool() -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new()
        .num_threads(2)
        .start_handler(|_| COUNTED.with(|c| c.set(true)))
        .build()
        .unwrap()
}

/// Allocations and bytes of one `trainer.step()` run on `pool`.
fn counted_step(pool: &rayon::ThreadPool, trainer: &mut Trainer) -> (u64, u64) {
    ALLOCATIONS.store(0, Ordering::SeqCst);
    BYTES.store(0, Ordering::SeqCst);
    ACTIVE.store(true, Ordering::SeqCst);
    pool.install(|| trainer.step().unwrap());
    ACTIVE.store(false, Ordering::SeqCst);
    (
        ALLOCATIONS.load(Ordering::SeqCst),
        BYTES.load(Ordering::SeqCst),
    )
}

fn trainer(method: Method, data: &std::path::Path) -> Trainer {
    let mut c = TrainConfig::preset(Preset::Tiny).with_iterations(1_000);
    c.method = method;
    c.init_points = 600;
    c.warm_up = 12;
    // No densification in the measured iterations (a plan reallocates every per-Gaussian row
    // by design), but its statistics are accumulated as in a run.
    c.densify.schedule.from = 999;
    c.densify.schedule.until = 1_000;
    let views = load_split(
        data,
        Split::Train,
        c.time_from,
        c.background.rgb(),
        c.downscale,
    )
    .unwrap();
    Trainer::new(c, views).unwrap()
}

/// Before the warm-up ends (no network), a warmed-up iteration allocates nothing at all: the
/// view order, the rasterizer's forward output and backward scratch, the loss, the gradient
/// rows, the densification statistics and every Adam step reuse their buffers.
///
/// After it, what allocates is the networks' own passes (tiny-nn and evo-state), which this
/// change leaves as they are: per parallel task, tiny-nn's block scratch (`map_init`) and the
/// gradient vector of each of its eight reduction groups with their item lists; the copy of the
/// outputs `forward_into` returns; the named parameter lists (`params_mut`, one `String` per
/// buffer) of the network's Adam step; for EvoGS, Φ's encoder gradients, the flattened Φ
/// gradient, evo-state's per-chunk Ψ-input sums, dL/dK and the chunk partial sums. Their number
/// depends on how rayon splits the work, so the bound below (measured: 61 for the baseline, 85
/// for EvoGS, on two threads) has room; its point is that nothing else creeps back in.
#[test]
fn a_warmed_up_iteration_allocates_nothing_outside_the_networks() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("scene");
    common::write_scene(&data);
    let pool = counted_pool();
    for method in [Method::Baseline, Method::Evogs] {
        let mut t = trainer(method, &data);
        // Buffers sized on the first iterations grow while the splats grow (each growth at
        // least doubles them); by the fifth they hold every later size of this scene.
        for _ in 0..4 {
            pool.install(|| t.step().unwrap());
        }
        for _ in 0..6 {
            let (count, bytes) = counted_step(&pool, &mut t);
            assert_eq!(
                (count, bytes),
                (0, 0),
                "{method}: iteration {} before the warm-up's end allocated",
                t.iteration()
            );
        }
        while t.iteration() < 14 {
            pool.install(|| t.step().unwrap());
        }
        let (count, bytes) = counted_step(&pool, &mut t);
        assert!(
            count <= 160,
            "{method}: an iteration with the network made {count} allocations ({bytes} bytes)"
        );
    }
}
