//! Data that stays on the device: typed buffers, kernels recorded into one pending command
//! encoder, and downloads that submit everything recorded so far and wait once.
//!
//! Uploads go into new buffers created with their contents (never `queue.write_buffer` into a
//! buffer that recorded work may still read: such writes land at the next submit, before the
//! work recorded earlier).

use super::buffer::{storage_from, storage_output, uniform_from};
use super::kernel::{Kernel, Workgroups};
use super::GpuBackend;
use crate::backend::Element;
use crate::error::{Error, Result};
use std::marker::PhantomData;

/// Uniform buffers kept for reuse (GpuBackend::uniform), enough for a pass of the fold push
/// (29 distinct structs). Few, although each is a few hundred bytes: a kept buffer keeps the
/// device memory block it was carved from, and 1024 of them raised the half phantom's peak
/// memory on lavapipe from 626 to 747 MiB (BENCHMARKS.md, thirty-first session).
const UNIFORMS_KEPT: usize = 64;

/// `len` elements of `T` in a device storage buffer.
pub struct GpuBuffer<T> {
    buffer: wgpu::Buffer,
    len: usize,
    _element: PhantomData<T>,
}

impl<T> Clone for GpuBuffer<T> {
    /// Another handle to the same device buffer.
    fn clone(&self) -> Self {
        GpuBuffer {
            buffer: self.buffer.clone(),
            len: self.len,
            _element: PhantomData,
        }
    }
}

impl<T: Element> GpuBuffer<T> {
    /// Elements held.
    pub fn len(&self) -> usize {
        self.len
    }

    /// True when it holds nothing.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// The wgpu buffer, to bind.
    pub fn raw(&self) -> &wgpu::Buffer {
        &self.buffer
    }

    fn bytes(&self) -> u64 {
        (self.len * std::mem::size_of::<T>()) as u64
    }
}

impl GpuBackend {
    /// A new device buffer holding `data`.
    pub fn upload_buffer<T: Element>(&self, what: &str, data: &[T]) -> Result<GpuBuffer<T>> {
        // wgpu refuses empty bindings: an empty array is stored as one zero element.
        let zero = [T::zeroed()];
        let contents = if data.is_empty() { &zero[..] } else { data };
        Ok(GpuBuffer {
            buffer: storage_from(self.context(), what, contents)?,
            len: data.len(),
            _element: PhantomData,
        })
    }

    /// A new device buffer of `len` elements for a kernel to write.
    pub fn output_buffer<T: Element>(&self, what: &str, len: usize) -> Result<GpuBuffer<T>> {
        Ok(GpuBuffer {
            buffer: storage_output::<T>(self.context(), what, len.max(1))?,
            len,
            _element: PhantomData,
        })
    }

    /// Records one dispatch of `kernel` with `params` at binding 0 and `buffers` after it; it
    /// runs at the next download.
    pub fn record<P: bytemuck::Pod>(
        &self,
        kernel: &Kernel,
        params: &P,
        buffers: &[&wgpu::Buffer],
        workgroups: [u32; 3],
    ) -> Result<()> {
        self.record_dispatch(kernel, params, buffers, Workgroups::Direct(workgroups))
    }

    /// Records one dispatch of `kernel` as [`GpuBackend::record`] does, its workgroup counts
    /// read from `args` at byte `offset` when it runs (written there by a kernel before it).
    pub fn record_indirect<P: bytemuck::Pod>(
        &self,
        kernel: &Kernel,
        params: &P,
        buffers: &[&wgpu::Buffer],
        (args, offset): (&wgpu::Buffer, u64),
    ) -> Result<()> {
        self.record_dispatch(kernel, params, buffers, Workgroups::Indirect(args, offset))
    }

    fn record_dispatch<P: bytemuck::Pod>(
        &self,
        kernel: &Kernel,
        params: &P,
        buffers: &[&wgpu::Buffer],
        workgroups: Workgroups,
    ) -> Result<()> {
        let ctx = self.context();
        let uniform = self.uniform(params)?;
        let mut bound = vec![&uniform];
        bound.extend_from_slice(buffers);
        self.note_dispatch_bytes(bound.iter().map(|b| b.size()).sum());
        self.recording(|encoder| kernel.dispatch(ctx, encoder, &bound, workgroups))
    }

    /// A uniform buffer holding `params`: one made earlier for the same bytes when there is
    /// one (uniform buffers are never written after they are made, so recorded work can share
    /// them), else a new one. A kernel dispatched again and again with the same parameters
    /// (each colour of the fold push, every sweep) sends them up once.
    fn uniform<P: bytemuck::Pod>(&self, params: &P) -> Result<wgpu::Buffer> {
        let bytes = bytemuck::bytes_of(params).to_vec();
        let mut made = self
            .uniforms
            .lock()
            .expect("no kernel panicked while recording");
        if let Some(uniform) = made.get(&bytes) {
            return Ok(uniform.clone());
        }
        if made.len() >= UNIFORMS_KEPT {
            made.clear();
        }
        let uniform = uniform_from(self.context(), "kernel parameters", params)?;
        made.insert(bytes, uniform.clone());
        Ok(uniform)
    }

    /// Records a copy of `from` into `to` (as long as `from`), after the work recorded so far.
    pub fn record_copy<T: Element>(&self, from: &GpuBuffer<T>, to: &GpuBuffer<T>) -> Result<()> {
        self.recording(|encoder| {
            if from.bytes() > 0 {
                encoder.copy_buffer_to_buffer(&from.buffer, 0, &to.buffer, 0, from.bytes());
            }
            Ok(())
        })
    }

    /// Runs `record` on the encoder of the work recorded so far (a new one when there is none).
    fn recording(
        &self,
        record: impl FnOnce(&mut wgpu::CommandEncoder) -> Result<()>,
    ) -> Result<()> {
        let ctx = self.context();
        let mut pending = self
            .pending
            .lock()
            .expect("no kernel panicked while recording");
        record(
            pending.get_or_insert_with(|| ctx.device.create_command_encoder(&Default::default())),
        )
    }

    /// Submits the recorded work with copies of `buffers` into one staging buffer, waits once,
    /// and returns their contents.
    pub fn download_buffers<T: Element>(&self, buffers: &[&GpuBuffer<T>]) -> Result<Vec<Vec<T>>> {
        let ctx = self.context();
        let total: u64 = buffers.iter().map(|b| b.bytes()).sum();
        let staging = ctx.scoped("staging buffer", || {
            ctx.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("staging"),
                size: total.max(4),
                usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            })
        })?;
        {
            // The pending work is taken and submitted under one lock: another thread sharing
            // this backend may have recorded kernels into it that its own next download reads,
            // and that download must not be submitted before them.
            let mut pending = self
                .pending
                .lock()
                .expect("no kernel panicked while recording");
            let mut encoder = pending
                .take()
                .unwrap_or_else(|| ctx.device.create_command_encoder(&Default::default()));
            let mut offset = 0;
            for b in buffers {
                if b.bytes() > 0 {
                    encoder.copy_buffer_to_buffer(&b.buffer, 0, &staging, offset, b.bytes());
                }
                offset += b.bytes();
            }
            ctx.scoped("submit", || ctx.queue.submit([encoder.finish()]))?;
        }
        ctx.counters.submit();
        ctx.counters.down(total);
        let bytes = super::buffer::map_and_read(ctx, &staging)?;
        // The staging buffer is at least 4 bytes (wgpu refuses empty ones): only `total` of them
        // were copied.
        let mut all: Vec<T> = bytemuck::pod_collect_to_vec(&bytes[..total as usize]);
        let mut out = Vec::with_capacity(buffers.len());
        for b in buffers.iter().rev() {
            out.push(all.split_off(all.len() - b.len));
        }
        out.reverse();
        if !all.is_empty() {
            return Err(Error::Gpu("read-back sizes do not add up".into()));
        }
        Ok(out)
    }
}
