//! One compute pipeline with an explicit bind group layout, built from an assembled WGSL
//! kernel (see crate::shaders), and the encoding of one dispatch of it.

use super::context::GpuContext;
use crate::error::{Error, Result};
use crate::shaders;

/// How a kernel's binding is declared in its shader.
#[derive(Clone, Copy, Debug)]
pub enum Binding {
    /// `var<uniform>`
    Uniform,
    /// `var<storage, read>`
    Read,
    /// `var<storage, read_write>`
    ReadWrite,
}

/// A compiled kernel.
pub struct Kernel {
    name: &'static str,
    pipeline: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
}

impl Kernel {
    /// Compiles kernel `name` (entry point `main`) whose group 0 holds `bindings` in order.
    pub fn new(ctx: &GpuContext, name: &'static str, bindings: &[Binding]) -> Result<Self> {
        let source = shaders::source(name);
        ctx.scoped(&format!("compiling kernel {name}"), || {
            let module = ctx
                .device
                .create_shader_module(wgpu::ShaderModuleDescriptor {
                    label: Some(name),
                    source: wgpu::ShaderSource::Wgsl(source.into()),
                });
            let entries: Vec<wgpu::BindGroupLayoutEntry> = bindings
                .iter()
                .enumerate()
                .map(|(i, b)| wgpu::BindGroupLayoutEntry {
                    binding: i as u32,
                    visibility: wgpu::ShaderStages::COMPUTE,
                    ty: wgpu::BindingType::Buffer {
                        ty: match b {
                            Binding::Uniform => wgpu::BufferBindingType::Uniform,
                            Binding::Read => wgpu::BufferBindingType::Storage { read_only: true },
                            Binding::ReadWrite => {
                                wgpu::BufferBindingType::Storage { read_only: false }
                            }
                        },
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                    count: None,
                })
                .collect();
            let layout = ctx
                .device
                .create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                    label: Some(name),
                    entries: &entries,
                });
            let pipeline_layout =
                ctx.device
                    .create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                        label: Some(name),
                        bind_group_layouts: &[Some(&layout)],
                        immediate_size: 0,
                    });
            let pipeline = ctx
                .device
                .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                    label: Some(name),
                    layout: Some(&pipeline_layout),
                    module: &module,
                    entry_point: Some("main"),
                    compilation_options: Default::default(),
                    cache: None,
                });
            Kernel {
                name,
                pipeline,
                layout,
            }
        })
    }

    /// Records one dispatch of `workgroups` with `buffers` bound to bindings 0, 1, ...
    pub fn dispatch(
        &self,
        ctx: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        buffers: &[&wgpu::Buffer],
        workgroups: Workgroups,
    ) -> Result<()> {
        let max = ctx.limits.max_compute_workgroups_per_dimension;
        if let Workgroups::Direct(counts) = workgroups {
            if counts.iter().any(|&w| w > max) {
                return Err(Error::InvalidInput(format!(
                    "kernel {}: {counts:?} workgroups exceed the device's {max} per dimension",
                    self.name
                )));
            }
        }
        ctx.counters.dispatch();
        ctx.scoped(&format!("dispatching kernel {}", self.name), || {
            let entries: Vec<wgpu::BindGroupEntry> = buffers
                .iter()
                .enumerate()
                .map(|(i, b)| wgpu::BindGroupEntry {
                    binding: i as u32,
                    resource: b.as_entire_binding(),
                })
                .collect();
            let group = ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some(self.name),
                layout: &self.layout,
                entries: &entries,
            });
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some(self.name),
                timestamp_writes: None,
            });
            pass.set_pipeline(&self.pipeline);
            pass.set_bind_group(0, &group, &[]);
            match workgroups {
                Workgroups::Direct([x, y, z]) => pass.dispatch_workgroups(x, y, z),
                Workgroups::Indirect(args, offset) => {
                    pass.dispatch_workgroups_indirect(args, offset)
                }
            }
        })
    }
}

/// How many workgroups a dispatch runs.
#[derive(Clone, Copy)]
pub enum Workgroups<'a> {
    /// These, known when it is recorded.
    Direct([u32; 3]),
    /// Three u32 a kernel wrote into this buffer at this byte offset before the dispatch runs
    /// (a kernel that bounds them by ROW_GROUPS and the list's length keeps them within the
    /// device's limit).
    Indirect(&'a wgpu::Buffer, u64),
}

/// Workgroups needed to cover `n` items with groups of `size`.
pub fn groups(n: usize, size: u32) -> u32 {
    n.div_ceil(size as usize) as u32
}

/// Workgroups of `size`³ covering a grid of `dims` ([nx, ny, nz, _] as the parameter structs
/// hold it).
pub fn cover(dims: [u32; 4], size: u32) -> [u32; 3] {
    [dims[0], dims[1], dims[2]].map(|n| groups(n as usize, size))
}
