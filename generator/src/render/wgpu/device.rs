//! Adapter choice: which wgpu backends a config allows and how adapters rank (a GPU first).

use super::*;

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
