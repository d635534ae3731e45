//! `mcdenoise info`: the Vulkan devices, the one used, the limits that matter.

use anyhow::bail;

use crate::Cli;

pub fn run(cli: &Cli) -> anyhow::Result<()> {
    let devices = mcdenoise::enumerate_devices()?;
    let chosen = mcdenoise::choose_device(&devices, cli.device.as_deref()).ok();
    if devices.is_empty() {
        bail!("the Vulkan loader found no device; for the software device: apt-get install mesa-vulkan-drivers");
    }
    let yes_no = |b: bool| if b { "yes" } else { "no" };
    for d in &devices {
        let mark = if Some(d.index) == chosen { "*" } else { " " };
        println!(
            "{mark} [{}] {} ({:?}, Vulkan {}.{}.{}, driver {})",
            d.index, d.name, d.kind, d.api_version.0, d.api_version.1, d.api_version.2, d.driver
        );
        let rows = [
            (
                "maxStorageBufferRange",
                format!(
                    "{} bytes ({} MiB)",
                    d.max_storage_buffer_range,
                    d.max_storage_buffer_range / (1 << 20)
                ),
            ),
            (
                "storage buffers per stage",
                d.max_per_stage_storage_buffers.to_string(),
            ),
            (
                "device-local heap",
                format!(
                    "{} MiB (default memory cap {} MiB)",
                    d.device_local_heap >> 20,
                    mcdenoise::default_memory_cap(d) >> 20
                ),
            ),
            ("shaderFloat64", yes_no(d.shader_float64).into()),
            ("shaderInt64", yes_no(d.shader_int64).into()),
            ("subgroup size", d.subgroup_size.to_string()),
            ("shared memory", format!("{} bytes", d.max_shared_memory)),
            (
                "push constants",
                format!("{} bytes", d.max_push_constants_size),
            ),
            ("timestamp period", format!("{} ns", d.timestamp_period_ns)),
            ("compute queue", yes_no(d.has_compute_queue).into()),
        ];
        for (name, value) in rows {
            println!("      {name:<26} {value}");
        }
    }
    if chosen.is_none() {
        bail!("no usable device among these");
    }
    println!("* = would be used (override with --device or MCDENOISE_DEVICE)");
    Ok(())
}
