//! Adapter choice: which wgpu backends a config allows, how adapters rank (a GPU first), and
//! the device opened on the chosen one.

use std::sync::{Condvar, Mutex, PoisonError};

use super::*;

pub(super) struct OpenDevice {
    pub(super) device: wgpu::Device,
    pub(super) queue: wgpu::Queue,
    pub(super) info: wgpu::AdapterInfo,
    pub(super) max_texture_size: u32,
}

/// A turn at creating or tearing down a Vulkan instance and device: one at a time in the
/// process. With 16 workers ending together, NVIDIA's Vulkan driver (580.159, an H200) deadlocked
/// in 2 of 6 runs inside concurrent `vkDestroyDevice` and `vkDestroyInstance` calls (every worker
/// waiting for the Vulkan loader's lock, its holder waiting inside the driver). Only the opening
/// and the teardown take turns; the workers render at the same time as before.
pub(super) struct DeviceTurn {
    held: bool,
}

static DEVICE_TURN: (Mutex<bool>, Condvar) = (Mutex::new(false), Condvar::new());

impl DeviceTurn {
    /// Not holding the turn (a renderer's until it is dropped).
    pub(super) fn none() -> Self {
        DeviceTurn { held: false }
    }

    /// Waits for the turn; it passes on when this is dropped.
    pub(super) fn take() -> Self {
        let (busy, freed) = &DEVICE_TURN;
        let mut busy = busy.lock().unwrap_or_else(PoisonError::into_inner);
        while *busy {
            busy = freed.wait(busy).unwrap_or_else(PoisonError::into_inner);
        }
        *busy = true;
        DeviceTurn { held: true }
    }
}

impl Drop for DeviceTurn {
    fn drop(&mut self) {
        if self.held {
            let (busy, freed) = &DEVICE_TURN;
            *busy.lock().unwrap_or_else(PoisonError::into_inner) = false;
            freed.notify_one();
        }
    }
}

/// Opens a device on the best adapter the config allows that can render to R32Float targets.
pub(super) fn open_device(cfg: &RendererConfig) -> Result<OpenDevice> {
    let _turn = DeviceTurn::take();
    // With `auto`, the native APIs are probed first and GL only when they offer nothing: GL
    // needs Mesa overrides for float targets, and probing EGL is noisy on headless machines.
    let tries = match cfg.backend {
        Backend::Auto => vec![wgpu::Backends::PRIMARY, wgpu::Backends::SECONDARY],
        b => vec![backends(b)],
    };
    let mut adapters = Vec::new();
    for b in tries {
        let mut desc = wgpu::InstanceDescriptor::new_without_display_handle_from_env();
        desc.backends = b;
        let instance = wgpu::Instance::new(desc);
        adapters = pollster::block_on(instance.enumerate_adapters(b));
        if !adapters.is_empty() {
            break;
        }
    }
    if adapters.is_empty() {
        bail!(
            "no graphics adapter found for backend {:?}. On a machine without a GPU install Mesa's CPU Vulkan driver: \
             `sudo apt-get install mesa-vulkan-drivers libvulkan1` (Debian/Ubuntu)",
            cfg.backend
        );
    }
    let names: Vec<String> = adapters.iter().map(|a| describe_adapter(&a.get_info())).collect();
    if let Some(want) = &cfg.adapter {
        adapters.retain(|a| a.get_info().name.to_lowercase().contains(&want.to_lowercase()));
        if adapters.is_empty() {
            bail!("no adapter name contains '{want}'; found: {}", names.join("; "));
        }
    }
    // Depth and mask targets are R32Float: an adapter that cannot render to it (Mesa's GL
    // llvmpipe without overrides) would fail at pipeline creation, deep inside wgpu.
    let float_target =
        |a: &wgpu::Adapter| a.get_texture_format_features(DEPTH_FORMAT).allowed_usages.contains(wgpu::TextureUsages::RENDER_ATTACHMENT);
    if !adapters.iter().any(float_target) {
        bail!(
            "no graphics adapter can render to R32Float targets (found: {}). On a machine without a GPU install \
             Mesa's CPU Vulkan driver: `sudo apt-get install mesa-vulkan-drivers libvulkan1` (Debian/Ubuntu, \
             or run scripts/system-deps)",
            names.join("; ")
        );
    }
    adapters.retain(float_target);
    adapters.sort_by_key(|a| rank(&a.get_info()));
    let adapter = adapters.into_iter().next().expect("non-empty");
    let info = adapter.get_info();
    let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
        label: Some("vtgen"),
        required_features: wgpu::Features::empty(),
        required_limits: wgpu::Limits::downlevel_defaults().using_resolution(adapter.limits()),
        experimental_features: wgpu::ExperimentalFeatures::disabled(),
        memory_hints: wgpu::MemoryHints::Performance,
        trace: wgpu::Trace::Off,
    }))
    .with_context(|| format!("cannot open a device on {}", describe_adapter(&info)))?;
    Ok(OpenDevice { device, queue, info, max_texture_size: adapter.limits().max_texture_dimension_2d })
}

pub(super) fn backends(b: Backend) -> wgpu::Backends {
    match b {
        Backend::Auto => wgpu::Backends::all(),
        Backend::Vulkan => wgpu::Backends::VULKAN,
        Backend::Gl => wgpu::Backends::GL,
        Backend::Metal => wgpu::Backends::METAL,
        Backend::Dx12 => wgpu::Backends::DX12,
    }
}

/// Preference among adapters: real GPUs first, then CPU rasterizers; Vulkan before GL, whose
/// R32Float targets need Mesa overrides.
pub(super) fn rank(info: &wgpu::AdapterInfo) -> (u8, u8) {
    let kind = match info.device_type {
        wgpu::DeviceType::DiscreteGpu => 0,
        wgpu::DeviceType::IntegratedGpu => 1,
        wgpu::DeviceType::VirtualGpu => 2,
        wgpu::DeviceType::Other => 3,
        wgpu::DeviceType::Cpu => 4,
    };
    let api = match info.backend {
        wgpu::Backend::Vulkan | wgpu::Backend::Metal | wgpu::Backend::Dx12 => 0,
        _ => 1,
    };
    (kind, api)
}

pub fn describe_adapter(info: &wgpu::AdapterInfo) -> String {
    let driver = if info.driver_info.is_empty() { String::new() } else { format!(" ({})", info.driver_info) };
    format!("{}{driver} [{:?}, {:?}]", info.name, info.backend, info.device_type)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::{AtomicUsize, Ordering};

    /// Threads taking turns never hold one together, and a dropped turn passes on.
    #[test]
    fn one_device_turn_at_a_time() {
        let (inside, most) = (AtomicUsize::new(0), AtomicUsize::new(0));
        std::thread::scope(|s| {
            for _ in 0..8 {
                s.spawn(|| {
                    for _ in 0..50 {
                        let turn = DeviceTurn::take();
                        let n = inside.fetch_add(1, Ordering::SeqCst) + 1;
                        most.fetch_max(n, Ordering::SeqCst);
                        std::thread::yield_now();
                        inside.fetch_sub(1, Ordering::SeqCst);
                        drop(turn);
                    }
                });
            }
        });
        assert_eq!(most.load(Ordering::SeqCst), 1);
        drop(DeviceTurn::none());
        drop(DeviceTurn::take()); // free again
    }
}
