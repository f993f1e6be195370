//! Buffer helpers: storage buffers sized against the device limits (a too large scene is an
//! error, not a panic), made per call or kept between calls in the context's
//! [`pool`](crate::pool), uploads, and blocking read-backs through a pooled staging buffer.

use std::num::NonZeroU64;
use std::sync::Arc;

use wgpu::util::DeviceExt;

use crate::context::GpuContext;
use crate::error::GpuError;

/// Usage of every storage buffer of the backend (copies both ways, so any can be cleared, read
/// back or handed to the sort).
pub const STORAGE: wgpu::BufferUsages = wgpu::BufferUsages::STORAGE
    .union(wgpu::BufferUsages::COPY_SRC)
    .union(wgpu::BufferUsages::COPY_DST);

fn too_large(device: &wgpu::Device, label: &'static str, bytes: u64) -> Result<(), GpuError> {
    let limit = binding_limit(device);
    if bytes > limit {
        return Err(GpuError {
            stage: "buffers",
            message: format!(
                "buffer {label} needs {bytes} bytes, the device allows {limit} per binding"
            ),
        });
    }
    Ok(())
}

/// A zero-initialised storage buffer of `bytes` bytes (at least 64, one record, so that empty
/// scenes still bind something).
pub fn storage(
    ctx: &GpuContext,
    label: &'static str,
    bytes: u64,
) -> Result<wgpu::Buffer, GpuError> {
    let bytes = bytes.max(64).next_multiple_of(4);
    too_large(&ctx.device, label, bytes)?;
    ctx.traffic.buffer();
    Ok(ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size: bytes,
        usage: STORAGE,
        mapped_at_creation: false,
    }))
}

/// The largest buffer `device` allows to bind as storage.
fn binding_limit(device: &wgpu::Device) -> u64 {
    device
        .limits()
        .max_storage_buffer_binding_size
        .min(device.limits().max_buffer_size)
}

/// [`BufferPool::take`](crate::pool::BufferPool::take) on the context's pool, a new buffer
/// counted on its traffic.
fn take(
    ctx: &GpuContext,
    label: &'static str,
    usage: wgpu::BufferUsages,
    bytes: u64,
    max_bytes: u64,
) -> crate::pool::Taken {
    let taken = ctx.pool.take(&ctx.device, label, usage, bytes, max_bytes);
    if !taken.reused {
        ctx.traffic.buffer();
    }
    taken
}

/// [`storage`] from the context's [`pool`](crate::pool) (a buffer made before when nobody holds
/// it any more, possibly larger than asked for): zero-filled like a new one, a reused buffer
/// cleared on the device by a command recorded into `encoder` (so before the work recorded
/// after this call; nothing crosses from the host). Bind it whole or by the size asked for:
/// the kernels here read counts from their uniforms, never a binding's length.
pub fn pooled_storage(
    ctx: &GpuContext,
    encoder: &mut wgpu::CommandEncoder,
    label: &'static str,
    bytes: u64,
) -> Result<Arc<wgpu::Buffer>, GpuError> {
    let bytes = bytes.max(64).next_multiple_of(4);
    too_large(&ctx.device, label, bytes)?;
    let taken = take(ctx, label, STORAGE, bytes, binding_limit(&ctx.device));
    if taken.reused {
        encoder.clear_buffer(&taken.buffer, 0, None);
    }
    Ok(taken.buffer)
}

/// [`storage_init`] from the context's [`pool`](crate::pool): `data` (padded to at least 64
/// bytes) written through the queue, counted as an upload; the rest of a reused buffer cleared
/// by a command recorded into `encoder`.
///
/// The caller holds the buffer until the work that reads it has been submitted: the write lands
/// at the start of the queue's next submission, so a buffer dropped before its work is submitted
/// could be handed out again and written over before that work runs.
pub fn pooled_storage_init(
    ctx: &GpuContext,
    encoder: &mut wgpu::CommandEncoder,
    label: &'static str,
    data: &[u8],
) -> Result<Arc<wgpu::Buffer>, GpuError> {
    let len = (data.len() as u64).max(64);
    too_large(&ctx.device, label, len)?;
    let end = len.next_multiple_of(4);
    let taken = take(ctx, label, STORAGE, end, binding_limit(&ctx.device));
    ctx.traffic.upload(len);
    write_padded(ctx, &taken.buffer, data);
    if taken.reused && end < taken.buffer.size() {
        encoder.clear_buffer(&taken.buffer, end, None);
    }
    Ok(taken.buffer)
}

/// [`uniform`] from the context's [`pool`](crate::pool): `data` written through the queue,
/// counted as an upload. The caller holds the buffer until the work that reads it has been
/// submitted (as [`pooled_storage_init`]).
pub fn pooled_uniform(ctx: &GpuContext, label: &'static str, data: &[u8]) -> Arc<wgpu::Buffer> {
    let len = data.len() as u64;
    let taken = take(
        ctx,
        label,
        wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
        len,
        len,
    );
    ctx.traffic.upload(len);
    ctx.queue.write_buffer(&taken.buffer, 0, data);
    taken.buffer
}

/// Writes `data` at the start of `buffer`, zero-padded to 64 bytes and to a multiple of 4 (the
/// queue's copy alignment); not counted.
fn write_padded(ctx: &GpuContext, buffer: &wgpu::Buffer, data: &[u8]) {
    if data.len() >= 64 && data.len().is_multiple_of(4) {
        ctx.queue.write_buffer(buffer, 0, data);
    } else {
        let mut padded = data.to_vec();
        padded.resize(data.len().max(64).next_multiple_of(4), 0);
        ctx.queue.write_buffer(buffer, 0, &padded);
    }
}

/// A storage buffer holding `data` (padded to at least 64 bytes).
pub fn storage_init(
    ctx: &GpuContext,
    label: &'static str,
    data: &[u8],
) -> Result<wgpu::Buffer, GpuError> {
    let device = &ctx.device;
    too_large(device, label, data.len() as u64)?;
    ctx.traffic.buffer();
    ctx.traffic.upload(data.len().max(64) as u64);
    if data.len() < 64 {
        let mut padded = [0u8; 64];
        padded[..data.len()].copy_from_slice(data);
        return Ok(
            device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents: &padded,
                usage: STORAGE,
            }),
        );
    }
    Ok(
        device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some(label),
            contents: data,
            usage: STORAGE,
        }),
    )
}

/// A uniform buffer holding `data`.
pub fn uniform(ctx: &GpuContext, label: &'static str, data: &[u8]) -> wgpu::Buffer {
    ctx.traffic.buffer();
    ctx.traffic.upload(data.len() as u64);
    ctx.device
        .create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some(label),
            contents: data,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
        })
}

/// Writes `data` into `buffer` at byte `offset` (through the queue: the write lands before the
/// next submitted work), counted as an upload. `data`'s length and `offset` are multiples of 4
/// and fit the buffer, or the write is a [`GpuError`] at stage `buffers`.
pub fn write(
    ctx: &GpuContext,
    buffer: &wgpu::Buffer,
    offset: u64,
    data: &[u8],
) -> Result<(), GpuError> {
    let len = data.len() as u64;
    if !offset.is_multiple_of(4)
        || !len.is_multiple_of(4)
        || offset
            .checked_add(len)
            .is_none_or(|end| end > buffer.size())
    {
        return Err(GpuError {
            stage: "buffers",
            message: format!(
                "a write of {len} bytes at {offset} into a buffer of {} bytes",
                buffer.size()
            ),
        });
    }
    if len > 0 {
        ctx.traffic.upload(len);
        ctx.queue.write_buffer(buffer, offset, data);
    }
    Ok(())
}

/// Copies `(buffer, byte offset, byte count)` regions to the host after the work already
/// recorded in `encoder`, submits, and blocks until they are read. On a context with
/// [`timestamps`](crate::timestamps) it also collects the spans ended since the last read-back
/// (16 bytes a span in the same copy; not counted as traffic: they are the measurement's).
pub fn read_back(
    ctx: &GpuContext,
    mut encoder: wgpu::CommandEncoder,
    regions: &[(&wgpu::Buffer, u64, u64)],
) -> Result<Vec<Vec<u8>>, GpuError> {
    let (device, queue) = (&ctx.device, &ctx.queue);
    let sizes: Vec<u64> = regions
        .iter()
        .map(|&(_, _, n)| n.next_multiple_of(4))
        .collect();
    let asked: u64 = sizes.iter().sum::<u64>();
    ctx.traffic.read_back(asked.max(4));
    let stamps = ctx
        .timestamps
        .as_ref()
        .and_then(|t| t.take().map(|c| (t, c)));
    let total = (asked + stamps.as_ref().map_or(0, |(_, c)| c.bytes())).max(4);
    // From the pool: held here until unmapped, then free for the next read-back.
    let staging = take(
        ctx,
        "read-back",
        wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        total,
        device.limits().max_buffer_size.max(total),
    )
    .buffer;
    let mut offset = 0;
    for (&(buffer, from, _), &size) in regions.iter().zip(&sizes) {
        if size > 0 {
            encoder.copy_buffer_to_buffer(buffer, from, &staging, offset, size);
        }
        offset += size;
    }
    if let Some((t, collection)) = &stamps {
        t.record(&mut encoder, collection, &staging, offset);
    }
    queue.submit([encoder.finish()]);
    let slice = staging.slice(..total);
    let (tx, rx) = std::sync::mpsc::channel();
    slice.map_async(wgpu::MapMode::Read, move |r| {
        // The receiver lives until `recv` below returns; a send error cannot happen.
        let _ = tx.send(r);
    });
    let gpu_err = |message: String| GpuError {
        stage: "read-back",
        message,
    };
    device
        .poll(wgpu::PollType::wait_indefinitely())
        .map_err(|e| gpu_err(e.to_string()))?;
    rx.recv()
        .map_err(|e| gpu_err(e.to_string()))?
        .map_err(|e| gpu_err(e.to_string()))?;
    let view = slice
        .get_mapped_range()
        .map_err(|e| gpu_err(e.to_string()))?;
    let mut out = Vec::with_capacity(regions.len());
    let mut offset = 0usize;
    for (&(_, _, n), &size) in regions.iter().zip(&sizes) {
        out.push(view[offset..offset + n as usize].to_vec());
        offset += size as usize;
    }
    if let Some((t, collection)) = stamps {
        let bytes = collection.bytes() as usize;
        t.add(collection, &view[offset..offset + bytes]);
    }
    drop(view);
    staging.unmap();
    Ok(out)
}

/// A compute bind-group layout entry for a storage buffer of u32/f32 words.
pub fn storage_entry(binding: u32, read_only: bool) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::COMPUTE,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Storage { read_only },
            has_dynamic_offset: false,
            min_binding_size: NonZeroU64::new(4),
        },
        count: None,
    }
}

/// A compute bind-group layout entry for binding 0, a uniform of `size` bytes read at a dynamic
/// offset (one record per dispatch in one buffer).
pub fn dynamic_uniform_entry(size: u64) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding: 0,
        visibility: wgpu::ShaderStages::COMPUTE,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Uniform,
            has_dynamic_offset: true,
            min_binding_size: NonZeroU64::new(size),
        },
        count: None,
    }
}

/// The first `words` u32 of `buffer` as a binding (at least one).
pub fn words(buffer: &wgpu::Buffer, words: u32) -> wgpu::BindingResource<'_> {
    wgpu::BindingResource::Buffer(wgpu::BufferBinding {
        buffer,
        offset: 0,
        size: NonZeroU64::new(4 * u64::from(words.max(1))),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn writes_land_where_asked_and_stray_ones_are_errors() {
        let ctx = GpuContext::new().expect("an adapter (CI installs lavapipe)");
        let buffer = storage(&ctx, "write test", 64).unwrap();
        for (offset, len) in [(2, 4), (0, 3), (64, 4), (61, 4), (u64::MAX - 3, 4)] {
            let err = write(&ctx, &buffer, offset, &vec![0; len]).unwrap_err();
            assert_eq!(err.stage, "buffers", "{offset} {len}");
        }
        let data = [1.5f32, -2.25];
        write(&ctx, &buffer, 8, bytemuck::cast_slice(&data)).unwrap();
        write(&ctx, &buffer, 60, &[]).unwrap();
        let encoder = ctx.device.create_command_encoder(&Default::default());
        let back = read_back(&ctx, encoder, &[(&buffer, 4, 12)]).unwrap();
        let got: Vec<f32> = bytemuck::pod_collect_to_vec(&back[0]);
        assert_eq!(got, [0.0, 1.5, -2.25]);
        // Only the write that landed counts as an upload.
        assert_eq!(ctx.traffic().bytes_up, 8);
    }
}

#[cfg(test)]
mod pool_tests {
    use std::sync::Arc;

    use super::STORAGE;
    use crate::GpuContext;
    use crate::pool::{BufferPool, MAX_FREE};

    /// The pool ([`crate::pool`]): held buffers are never handed out; free ones are, the
    /// smallest large enough first; new ones get a quarter of headroom; free ones too small are
    /// dropped when a larger one is made; no more than [`MAX_FREE`] free ones are kept; labels
    /// and usages do not share; only new buffers count as created.
    #[test]
    fn held_buffers_stay_theirs_and_free_ones_come_back() {
        let ctx = GpuContext::new().expect("an adapter (CI installs lavapipe)");
        let take = |label, bytes| super::take(&ctx, label, STORAGE, bytes, 1 << 20);
        let a = take("t", 100);
        assert!(!a.reused);
        assert_eq!(
            a.buffer.size(),
            128,
            "100 bytes and a quarter, to a multiple of 4"
        );
        let b = take("t", 100);
        assert!(!b.reused && !Arc::ptr_eq(&a.buffer, &b.buffer), "a is held");
        let a_ptr = Arc::clone(&a.buffer);
        drop(a);
        // Only `a_ptr` and the pool hold it now: still in use (a new 100-byte buffer, free
        // again at once).
        assert!(!take("t", 80).reused);
        drop(a_ptr);
        let again = take("t", 80);
        assert!(
            again.reused && again.buffer.size() == 100,
            "the smallest free one"
        );
        assert!(!take("u", 80).reused, "another label");
        let uniform = ctx.pool.take(
            &ctx.device,
            "t",
            wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            80,
            1 << 20,
        );
        assert!(!uniform.reused, "another usage");
        drop((again, b, uniform));
        // Larger than every free one: a new buffer, the free ones of its label dropped.
        let before = ctx.traffic();
        let big = take("t", 1000);
        assert!(!big.reused && big.buffer.size() == 1252);
        assert_eq!(ctx.traffic().since(&before).buffers_created, 1);
        let t_count = |pool: &BufferPool| pool.count("t", STORAGE);
        assert_eq!(
            t_count(&ctx.pool),
            1,
            "the smaller free buffers were dropped"
        );
        // Many held at once, then all dropped: at most MAX_FREE stay.
        let many: Vec<_> = (0..5).map(|_| take("t", 1000)).collect();
        drop((big, many));
        let before = ctx.traffic();
        let one = take("t", 10);
        assert!(one.reused);
        assert_eq!(ctx.traffic().since(&before).buffers_created, 0);
        assert!(t_count(&ctx.pool) <= MAX_FREE, "{}", t_count(&ctx.pool));
        drop(one);
        ctx.pool.trim();
        assert_eq!(t_count(&ctx.pool), 0);
    }
}
