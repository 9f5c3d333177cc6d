//! Choosing where kernels run: `--device auto|gpu|cpu`.

use crate::backend::Core;
use crate::cpu::CpuBackend;
use crate::error::Result;
use crate::gpu::context::{AdapterChoice, GpuContext};
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

/// Where the user wants kernels to run: the kind of backend and, for the GPU, which adapter.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct DeviceWanted {
    /// auto, gpu or cpu.
    pub kind: DeviceChoice,
    /// The adapter `--gpu` names (index or name); none: the best one.
    pub adapter: Option<AdapterChoice>,
}

impl DeviceWanted {
    /// The CPU backend.
    pub fn cpu() -> Self {
        DeviceWanted {
            kind: DeviceChoice::Cpu,
            adapter: None,
        }
    }
}

/// An opened backend of either kind; [`on_backend!`](crate::on_backend) runs code generic over
/// [`Backend`] on it.
pub enum Opened {
    /// The CPU backend.
    Cpu(CpuBackend),
    /// The GPU backend (boxed: it is much larger than the CPU backend).
    Gpu(Box<GpuBackend>),
}

impl Opened {
    /// What the backend is (see [`Backend::describe`]).
    pub fn describe(&self) -> String {
        crate::on_backend!(self, backend => backend.describe())
    }
}

/// `on_backend!(opened, backend => expression)`: the expression, with `backend` a reference to
/// the opened backend (its concrete type, so generic library calls take it).
#[macro_export]
macro_rules! on_backend {
    ($opened:expr, $backend:ident => $body:expr) => {
        match &$opened {
            $crate::device::Opened::Cpu($backend) => $body,
            $crate::device::Opened::Gpu(boxed) => {
                let $backend: &$crate::gpu::GpuBackend = boxed;
                $body
            }
        }
    };
}

/// Opens the chosen backend; also returns one line saying what was chosen and why.
pub fn open_backend(wanted: &DeviceWanted) -> Result<(Opened, String)> {
    let adapter = wanted.adapter.as_ref();
    match wanted.kind {
        DeviceChoice::Cpu => {
            let b = CpuBackend;
            let line = format!("device: {} (--device cpu)", b.describe());
            Ok((Opened::Cpu(b), line))
        }
        DeviceChoice::Gpu => {
            let b = GpuBackend::with_context(GpuContext::open(adapter)?)?;
            let line = format!("device: {}", b.describe());
            Ok((Opened::Gpu(Box::new(b)), line))
        }
        // An adapter named by --gpu is used even when it is a software driver.
        DeviceChoice::Auto if adapter.is_some() => {
            let b = GpuBackend::with_context(GpuContext::open(adapter)?)?;
            let line = format!("device: {} (--gpu)", b.describe());
            Ok((Opened::Gpu(Box::new(b)), line))
        }
        DeviceChoice::Auto => match GpuContext::new() {
            Ok(ctx) if !ctx.is_software() => {
                let b = GpuBackend::with_context(ctx)?;
                let line = format!("device: {} (auto)", b.describe());
                Ok((Opened::Gpu(Box::new(b)), line))
            }
            Ok(ctx) => Ok((
                Opened::Cpu(CpuBackend),
                format!(
                    "device: {} (auto: the only GPU is the software driver {}, slower than the \
                     CPU backend; --device gpu forces it)",
                    CpuBackend.describe(),
                    ctx.info.name
                ),
            )),
            Err(e) => Ok((
                Opened::Cpu(CpuBackend),
                format!("device: {} (auto: {e})", CpuBackend.describe()),
            )),
        },
    }
}
