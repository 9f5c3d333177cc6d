//! Choosing where kernels run: `--device auto|gpu|cpu`.

use crate::backend::Backend;
use crate::cpu::CpuBackend;
use crate::error::Result;
use crate::gpu::context::GpuContext;
use crate::gpu::GpuBackend;

/// The user's choice of backend.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum DeviceChoice {
    /// A hardware GPU when one is found, else the CPU backend. A software Vulkan driver
    /// (lavapipe) is slower than the CPU backend, so auto does not pick it.
    #[default]
    Auto,
    /// The GPU path (including a software Vulkan driver); an error when none is found.
    Gpu,
    /// The CPU backend.
    Cpu,
}

/// Opens the chosen backend; also returns one line saying what was chosen and why.
pub fn open_backend(choice: DeviceChoice) -> Result<(Box<dyn Backend>, String)> {
    match choice {
        DeviceChoice::Cpu => {
            let b = CpuBackend;
            let line = format!("device: {} (--device cpu)", b.describe());
            Ok((Box::new(b), line))
        }
        DeviceChoice::Gpu => {
            let b = GpuBackend::new()?;
            let line = format!("device: {}", b.describe());
            Ok((Box::new(b), line))
        }
        DeviceChoice::Auto => match GpuContext::new() {
            Ok(ctx) if !ctx.is_software() => {
                let b = GpuBackend::with_context(ctx)?;
                let line = format!("device: {} (auto)", b.describe());
                Ok((Box::new(b), line))
            }
            Ok(ctx) => Ok((
                Box::new(CpuBackend),
                format!(
                    "device: {} (auto: the only GPU is the software driver {}, slower than the \
                     CPU backend; --device gpu forces it)",
                    CpuBackend.describe(),
                    ctx.info.name
                ),
            )),
            Err(e) => Ok((
                Box::new(CpuBackend),
                format!("device: {} (auto: {e})", CpuBackend.describe()),
            )),
        },
    }
}
