//! Device buffers kept between calls: a [`BufferPool`] hands out a buffer it made before when
//! nobody else holds it any more, so that a backend called every iteration (the rasterizer's
//! twenty-odd buffers per forward pass) stops creating and freeing device memory per call.
//!
//! A buffer is free when the pool holds the only [`Arc`] to it: whoever took it still holds a
//! clone (a forward pass's output keeps the buffers its backward pass reads), so a held buffer is
//! never handed out twice. Buffers are found by label and usage, the smallest free one at least
//! as large as asked for; a new one is made a quarter larger than asked (the number of
//! (tile, Gaussian) pairs varies from view to view, and a little headroom spares most regrowths),
//! and the free buffers too small for it are dropped then. At most [`MAX_FREE`] free buffers of a
//! label and usage are kept (a caller that held many outputs at once does not keep their memory
//! after dropping them).
//!
//! What it is not: a sub-allocator (one wgpu buffer per request), nor shared between contexts.

use std::collections::HashMap;
use std::sync::{Arc, Mutex};
/// Free buffers kept per label and usage.
pub const MAX_FREE: usize = 2;

/// A label and the bits of a usage.
type Key = (&'static str, u32);

/// Buffers of one context, by label and usage, for reuse across calls.
#[derive(Debug, Default)]
pub struct BufferPool {
    slots: Mutex<HashMap<Key, Vec<Arc<wgpu::Buffer>>>>,
}

/// What [`BufferPool::take`] gave.
#[derive(Debug)]
pub struct Taken {
    /// The buffer (at least the size asked for; possibly larger).
    pub buffer: Arc<wgpu::Buffer>,
    /// Whether it was made before (its contents are whatever its last user left).
    pub reused: bool,
}

impl BufferPool {
    /// A buffer labelled `label` with `usage` of at least `bytes` bytes: a free one made before
    /// (the smallest that is large enough), else a new one of `bytes` plus a quarter (at most
    /// `max_bytes`, at least `bytes`). The contents of a reused buffer are its last user's;
    /// clearing it, and counting a new one on the context's traffic, are the caller's.
    pub fn take(
        &self,
        device: &wgpu::Device,
        label: &'static str,
        usage: wgpu::BufferUsages,
        bytes: u64,
        max_bytes: u64,
    ) -> Taken {
        let mut slots = self.slots.lock().unwrap_or_else(|e| e.into_inner());
        let slot = slots.entry((label, usage.bits())).or_default();
        // Only this pool holds a free buffer, and only through the lock is it cloned: a count
        // of one cannot rise while the lock is held.
        let free = |b: &Arc<wgpu::Buffer>| Arc::strong_count(b) == 1;
        let mut kept = 0;
        slot.retain(|b| {
            if !free(b) {
                return true;
            }
            kept += 1;
            kept <= MAX_FREE
        });
        if let Some(b) = slot
            .iter()
            .filter(|b| free(b) && b.size() >= bytes)
            .min_by_key(|b| b.size())
        {
            return Taken {
                buffer: Arc::clone(b),
                reused: true,
            };
        }
        slot.retain(|b| !free(b));
        let size = (bytes + bytes / 4)
            .next_multiple_of(4)
            .min(max_bytes)
            .max(bytes);
        let buffer = Arc::new(device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size,
            usage,
            mapped_at_creation: false,
        }));
        slot.push(Arc::clone(&buffer));
        Taken {
            buffer,
            reused: false,
        }
    }

    /// Buffers the pool holds (free or in use) and their bytes.
    pub fn held(&self) -> (usize, u64) {
        let slots = self.slots.lock().unwrap_or_else(|e| e.into_inner());
        slots
            .values()
            .flatten()
            .fold((0, 0), |(n, bytes), b| (n + 1, bytes + b.size()))
    }

    /// Buffers the pool holds (free or in use) of `label` and `usage`.
    pub fn count(&self, label: &'static str, usage: wgpu::BufferUsages) -> usize {
        let slots = self.slots.lock().unwrap_or_else(|e| e.into_inner());
        slots.get(&(label, usage.bits())).map_or(0, Vec::len)
    }

    /// Drops every free buffer (those in use stay until their holders drop them and a later
    /// [`BufferPool::take`] finds them free).
    pub fn trim(&self) {
        let mut slots = self.slots.lock().unwrap_or_else(|e| e.into_inner());
        for slot in slots.values_mut() {
            slot.retain(|b| Arc::strong_count(b) > 1);
        }
    }
}
