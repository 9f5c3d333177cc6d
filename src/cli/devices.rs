//! `posereg devices`: the GPUs Vulkan finds, numbered as `--gpu INDEX` counts them.

use posereg::gpu::context::list_adapters;

/// Prints one line per adapter: index, name, type, driver, and whether posereg can use it.
pub fn run() -> anyhow::Result<()> {
    let adapters = list_adapters();
    if adapters.is_empty() {
        println!("no Vulkan adapter found (posereg runs on the CPU backend: --device cpu)");
    }
    for (index, a) in adapters.iter().enumerate() {
        let usable = match a.has_f64 {
            true => "usable",
            false => "not usable: no 64-bit floats in shaders",
        };
        println!(
            "{index}: {} ({:?}, {:?}, driver {} {}) - {usable}",
            a.info.name, a.info.device_type, a.info.backend, a.info.driver, a.info.driver_info
        );
    }
    Ok(())
}
