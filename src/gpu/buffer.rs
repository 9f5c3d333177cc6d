//! Typed buffer helpers: every storage buffer is checked against the device's limits before it
//! is created, and read-backs go through one staging path.

use super::context::GpuContext;
use crate::error::{Error, Result};
use bytemuck::Pod;
use wgpu::util::DeviceExt;

/// A read-only storage buffer holding `data`.
pub fn storage_from<T: Pod>(ctx: &GpuContext, what: &str, data: &[T]) -> Result<wgpu::Buffer> {
    let bytes: &[u8] = bytemuck::cast_slice(data);
    ctx.check_storage(what, bytes.len() as u64)?;
    ctx.counters.up(bytes.len() as u64);
    ctx.scoped(what, || {
        ctx.device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(what),
                contents: bytes,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            })
    })
}

/// A writable storage buffer of `len` elements of `T`, readable back (and readable as a
/// dispatch's workgroup counts, for the kernels that write their own).
pub fn storage_output<T: Pod>(ctx: &GpuContext, what: &str, len: usize) -> Result<wgpu::Buffer> {
    let bytes = (len * std::mem::size_of::<T>()) as u64;
    ctx.check_storage(what, bytes)?;
    ctx.scoped(what, || {
        ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(what),
            size: bytes,
            usage: wgpu::BufferUsages::STORAGE
                | wgpu::BufferUsages::COPY_SRC
                | wgpu::BufferUsages::COPY_DST
                | wgpu::BufferUsages::INDIRECT,
            mapped_at_creation: false,
        })
    })
}

/// A uniform buffer holding one parameter struct.
pub fn uniform_from<T: Pod>(ctx: &GpuContext, what: &str, value: &T) -> Result<wgpu::Buffer> {
    ctx.counters.up(std::mem::size_of::<T>() as u64);
    ctx.scoped(what, || {
        ctx.device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(what),
                contents: bytemuck::bytes_of(value),
                usage: wgpu::BufferUsages::UNIFORM,
            })
    })
}

/// Submits `encoder` (with its dispatches), copies `len` elements of `source` into a staging
/// buffer in the same submission, waits, and returns them.
pub fn submit_and_read<T: Pod>(
    ctx: &GpuContext,
    mut encoder: wgpu::CommandEncoder,
    source: &wgpu::Buffer,
    len: usize,
) -> Result<Vec<T>> {
    let bytes = (len * std::mem::size_of::<T>()) as u64;
    let staging = ctx.scoped("staging buffer", || {
        ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("staging"),
            size: bytes,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        })
    })?;
    ctx.scoped("submit", || {
        encoder.copy_buffer_to_buffer(source, 0, &staging, 0, bytes);
        ctx.queue.submit([encoder.finish()]);
    })?;
    ctx.counters.submit();
    ctx.counters.down(bytes);
    let out = bytemuck::pod_collect_to_vec::<u8, T>(&map_and_read(ctx, &staging)?);
    Ok(out)
}

/// Waits for the device, maps `staging` (MAP_READ) and returns its bytes.
pub fn map_and_read(ctx: &GpuContext, staging: &wgpu::Buffer) -> Result<Vec<u8>> {
    let (sender, receiver) = std::sync::mpsc::channel();
    staging.map_async(wgpu::MapMode::Read, .., move |r| {
        let _ = sender.send(r);
    });
    ctx.device
        .poll(wgpu::PollType::wait_indefinitely())
        .map_err(|e| Error::Gpu(format!("waiting for the GPU: {e}")))?;
    receiver
        .recv()
        .map_err(|_| Error::Gpu("read-back was never answered".into()))?
        .map_err(|e| Error::Gpu(format!("mapping the read-back buffer: {e}")))?;
    let view = staging
        .get_mapped_range(..)
        .map_err(|e| Error::Gpu(format!("reading the read-back buffer: {e}")))?;
    let out = view.to_vec();
    drop(view);
    staging.unmap();
    Ok(out)
}
