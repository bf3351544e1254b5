//! Backend selection. burn 0.22 tensors carry their backend in their `Device`, so the model code
//! is backend-generic by construction: the same `PoseNet` runs on whichever device its tensors
//! are created on. Training wraps the device with autodiff.
//!
//! - `--device cpu` (default): burn's pure-Rust `flex` CPU backend. burn 0.22 deprecates ndarray
//!   in its favour, and it trains our networks several times faster (the tests' network: ~50 ms
//!   per training step vs ~300 ms, mostly the colour CNN's backward pass, in the dev profile);
//! - `--device ndarray`: the ndarray backend (also built by default);
//! - `--device wgpu` (or `wgpu:cpu`, `wgpu:discrete`, `wgpu:integrated`): burn's wgpu backend
//!   (cubecl) on any Vulkan, Metal or DX12 adapter; `wgpu` takes the best one wgpu finds,
//!   `wgpu:cpu` a CPU implementation such as Mesa's lavapipe (what CI tests). Built by default:
//!   a GPU trains without a CUDA toolchain or any download;
//! - `--device cuda[:N]`: CUDA (cargo feature `cuda`, not built by default).

use anyhow::{Result, bail};
use burn::tensor::{Device, DeviceKind};

/// The CPU device: burn's `flex` backend (what CI runs).
pub fn cpu() -> Device {
    Device::flex()
}

/// burn's ndarray backend (deprecated by burn 0.22, kept selectable).
#[allow(deprecated)]
pub fn ndarray() -> Device {
    Device::ndarray()
}

/// The device named on the command line (see the module docs).
pub fn parse(name: &str) -> Result<Device> {
    match name {
        "cpu" | "flex" => Ok(cpu()),
        "ndarray" => Ok(ndarray()),
        "wgpu" => Ok(Device::wgpu(DeviceKind::DefaultDevice)),
        "wgpu:cpu" => Ok(Device::wgpu(DeviceKind::Cpu)),
        "wgpu:discrete" => Ok(Device::wgpu(DeviceKind::DiscreteGpu(0))),
        "wgpu:integrated" => Ok(Device::wgpu(DeviceKind::IntegratedGpu(0))),
        n if n == "cuda" || n.starts_with("cuda:") => cuda(n.strip_prefix("cuda:").map(str::parse).transpose()?.unwrap_or(0)),
        other => {
            bail!("unknown device '{other}' (expected cpu, flex, ndarray, wgpu, wgpu:cpu, wgpu:discrete, wgpu:integrated, cuda or cuda:N)")
        }
    }
}

/// What `--device` accepts, for the command-line help.
pub const DEVICE_HELP: &str = "cpu (burn's flex CPU backend, default), ndarray, wgpu (best Vulkan/Metal/DX12 adapter), \
     wgpu:cpu (a CPU Vulkan driver such as lavapipe), wgpu:discrete, wgpu:integrated, cuda[:N] (build with --features cuda)";

#[cfg(feature = "cuda")]
fn cuda(index: usize) -> Result<Device> {
    Ok(Device::cuda(index))
}

#[cfg(not(feature = "cuda"))]
fn cuda(_index: usize) -> Result<Device> {
    bail!("this vtpose was built without CUDA: rebuild with `cargo build --release -p vt-trainer --features cuda`")
}

/// Whether `device` computes on the host's CPU cores through burn's own kernels (flex,
/// ndarray), where a training step splits its batch over threads.
pub fn is_cpu(device: &Device) -> bool {
    let plain = device.clone().without_autodiff();
    plain == cpu() || plain == ndarray()
}

/// Threads a batch is split over on `device`: `requested`, or with 0 the machine's cores on the
/// CPU backends and 1 on a GPU (one device queue gains nothing from more host threads).
pub fn batch_threads(requested: usize, device: &Device) -> usize {
    match requested {
        0 if is_cpu(device) => std::thread::available_parallelism().map_or(1, |n| n.get()),
        0 => 1,
        n => n,
    }
}

/// A short name of the device for reports.
pub fn describe(device: &Device) -> String {
    format!("{device:?}")
}
