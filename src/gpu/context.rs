//! The headless wgpu device: adapter choice, real limits, error capture.

use crate::backend::Traffic;
use crate::error::{Error, Result};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

/// A wgpu device and queue on a chosen adapter, with that adapter's real limits.
pub struct GpuContext {
    /// The logical device.
    pub device: wgpu::Device,
    /// Its queue.
    pub queue: wgpu::Queue,
    /// What the adapter is (name, driver, type).
    pub info: wgpu::AdapterInfo,
    /// The limits the device was created with (the adapter's own, not wgpu's defaults, so a
    /// 136×256×256 volume and its packed 3-vector field can be bound).
    pub limits: wgpu::Limits,
    /// Bytes moved and work launched on this device.
    pub counters: Counters,
}

/// The device's running [`Traffic`] totals, shared by every kernel call.
#[derive(Default)]
pub struct Counters {
    bytes_up: AtomicU64,
    bytes_down: AtomicU64,
    dispatches: AtomicU64,
    submits: AtomicU64,
}

impl Counters {
    /// Counts `bytes` written into device buffers.
    pub fn up(&self, bytes: u64) {
        self.bytes_up.fetch_add(bytes, Ordering::Relaxed);
    }

    /// Counts `bytes` read back.
    pub fn down(&self, bytes: u64) {
        self.bytes_down.fetch_add(bytes, Ordering::Relaxed);
    }

    /// Counts one dispatch.
    pub fn dispatch(&self) {
        self.dispatches.fetch_add(1, Ordering::Relaxed);
    }

    /// Counts one queue submission.
    pub fn submit(&self) {
        self.submits.fetch_add(1, Ordering::Relaxed);
    }

    /// The totals so far.
    pub fn read(&self) -> Traffic {
        Traffic {
            bytes_up: self.bytes_up.load(Ordering::Relaxed),
            bytes_down: self.bytes_down.load(Ordering::Relaxed),
            dispatches: self.dispatches.load(Ordering::Relaxed),
            submits: self.submits.load(Ordering::Relaxed),
        }
    }
}

fn type_rank(t: wgpu::DeviceType) -> u8 {
    match t {
        wgpu::DeviceType::DiscreteGpu => 0,
        wgpu::DeviceType::IntegratedGpu => 1,
        wgpu::DeviceType::VirtualGpu => 2,
        wgpu::DeviceType::Other => 3,
        wgpu::DeviceType::Cpu => 4,
    }
}

/// Which adapter `--gpu` asks for: its index in `posereg devices`' list, or a substring of its
/// name (case-insensitive).
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum AdapterChoice {
    /// The n-th adapter Vulkan lists (from 0).
    Index(usize),
    /// The first adapter whose name contains this.
    Name(String),
}

impl std::str::FromStr for AdapterChoice {
    type Err = std::convert::Infallible;

    /// Digits are an index, anything else a name.
    fn from_str(text: &str) -> std::result::Result<Self, Self::Err> {
        Ok(match text.parse::<usize>() {
            Ok(n) => AdapterChoice::Index(n),
            Err(_) => AdapterChoice::Name(text.to_lowercase()),
        })
    }
}

/// One adapter as `posereg devices` lists it.
#[derive(Clone, Debug)]
pub struct AdapterListing {
    /// Name, driver, type, backend.
    pub info: wgpu::AdapterInfo,
    /// Whether it offers the 64-bit floats posereg's RBF kernels need.
    pub has_f64: bool,
}

/// Every adapter Vulkan finds, in the order `--gpu INDEX` counts them. $WGPU_BACKEND limits
/// the backends searched.
pub fn list_adapters() -> Vec<AdapterListing> {
    enumerate()
        .iter()
        .map(|a| AdapterListing {
            info: a.get_info(),
            has_f64: a.features().contains(wgpu::Features::SHADER_F64),
        })
        .collect()
}

fn enumerate() -> Vec<wgpu::Adapter> {
    let instance =
        wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env());
    let backends = wgpu::Backends::from_env().unwrap_or(wgpu::Backends::all());
    pollster::block_on(instance.enumerate_adapters(backends))
}

/// The adapters `choice` (or, without one, $WGPU_ADAPTER_NAME) allows, in the order found.
fn allowed(
    adapters: Vec<wgpu::Adapter>,
    choice: Option<&AdapterChoice>,
) -> Result<Vec<wgpu::Adapter>> {
    let names: Vec<String> = adapters.iter().map(|a| a.get_info().name).collect();
    let from_env = std::env::var("WGPU_ADAPTER_NAME").ok();
    let (wanted, how) = match (choice, from_env) {
        (Some(AdapterChoice::Index(n)), _) => {
            let mut adapters = adapters;
            return match *n < adapters.len() {
                true => Ok(vec![adapters.swap_remove(*n)]),
                false => Err(Error::NoAdapter(format!(
                    "--gpu {n}: there are {} adapters, numbered from 0: {names:?}",
                    names.len()
                ))),
            };
        }
        (Some(AdapterChoice::Name(name)), _) => (name.clone(), "--gpu"),
        (None, Some(name)) => (name.to_lowercase(), "WGPU_ADAPTER_NAME"),
        (None, None) => return Ok(adapters),
    };
    let kept: Vec<wgpu::Adapter> = adapters
        .into_iter()
        .filter(|a| a.get_info().name.to_lowercase().contains(&wanted))
        .collect();
    match kept.is_empty() {
        true => Err(Error::NoAdapter(format!(
            "{how} {wanted:?} matches none of {names:?}"
        ))),
        false => Ok(kept),
    }
}

impl GpuContext {
    /// Opens the best adapter: the one `--gpu` or $WGPU_ADAPTER_NAME names, else a discrete
    /// GPU before an integrated one before a software rasteriser. $WGPU_BACKEND limits the
    /// backends searched (this build has Vulkan).
    pub fn new() -> Result<Self> {
        Self::open(None)
    }

    /// Opens the adapter `choice` names (see [`GpuContext::new`]).
    pub fn open(choice: Option<&AdapterChoice>) -> Result<Self> {
        let adapters = enumerate();
        if adapters.is_empty() {
            return Err(Error::NoAdapter(
                "no Vulkan device found; for the software driver (lavapipe) on Debian/Ubuntu \
                 run `apt-get install mesa-vulkan-drivers`, or install your GPU's Vulkan driver"
                    .into(),
            ));
        }
        let mut adapters = allowed(adapters, choice)?;
        adapters.sort_by_key(|a| type_rank(a.get_info().device_type));
        let adapter = adapters.remove(0);
        let info = adapter.get_info();
        let limits = adapter.limits();
        // The cubic RBF's terms cancel to a millionth of their size (shaders/nonrigid/rbf_lattice.wgsl):
        // its kernels run in f64, which Vulkan drivers on NVIDIA, AMD, Intel and lavapipe offer.
        if !adapter.features().contains(wgpu::Features::SHADER_F64) {
            return Err(Error::NoAdapter(format!(
                "{}: the GPU offers no 64-bit floats (SHADER_F64), which the RBF kernels need; \
                 use --device cpu",
                info.name
            )));
        }
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("posereg"),
            required_features: wgpu::Features::SHADER_F64,
            required_limits: limits.clone(),
            experimental_features: wgpu::ExperimentalFeatures::default(),
            memory_hints: wgpu::MemoryHints::Performance,
            trace: wgpu::Trace::Off,
        }))
        .map_err(|e| Error::NoAdapter(format!("{}: cannot open device: {e}", info.name)))?;
        // Errors are captured by error scopes around every operation; anything escaping them is
        // reported rather than aborting the process (wgpu's default handler panics).
        device.on_uncaptured_error(Arc::new(|e| {
            eprintln!("posereg: GPU error outside an error scope: {e}")
        }));
        Ok(GpuContext {
            device,
            queue,
            info,
            limits,
            counters: Counters::default(),
        })
    }

    /// True for software rasterisers (lavapipe/llvmpipe, SwiftShader): correct but slower than
    /// the CPU backend.
    pub fn is_software(&self) -> bool {
        self.info.device_type == wgpu::DeviceType::Cpu
    }

    /// "NAME (BACKEND, TYPE)".
    pub fn describe(&self) -> String {
        format!(
            "{} ({:?}, {:?})",
            self.info.name, self.info.backend, self.info.device_type
        )
    }

    /// Runs `f`, turning any validation or out-of-memory error it raises into an [`Error::Gpu`]
    /// naming `what`.
    pub fn scoped<T>(&self, what: &str, f: impl FnOnce() -> T) -> Result<T> {
        let oom = self.device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
        let validation = self.device.push_error_scope(wgpu::ErrorFilter::Validation);
        let out = f();
        let v = pollster::block_on(validation.pop());
        let o = pollster::block_on(oom.pop());
        match v.or(o) {
            Some(e) => Err(Error::Gpu(format!("{what}: {e}"))),
            None => Ok(out),
        }
    }

    /// Checks that a storage binding of `bytes` fits the device.
    pub fn check_storage(&self, what: &str, bytes: u64) -> Result<()> {
        let checks = [
            (
                self.limits.max_storage_buffer_binding_size,
                "max_storage_buffer_binding_size",
            ),
            (self.limits.max_buffer_size, "max_buffer_size"),
        ];
        for (limit, limit_name) in checks {
            if bytes > limit {
                return Err(Error::DeviceLimit {
                    what: what.to_string(),
                    needed: bytes,
                    limit,
                    limit_name,
                });
            }
        }
        Ok(())
    }
}
