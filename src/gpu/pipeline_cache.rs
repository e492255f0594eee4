//! The on-disk pipeline cache: loaded at context creation from
//! `$XDG_CACHE_HOME/surfel/` (or `~/.cache/surfel/`), checked against the device by the
//! Vulkan pipeline-cache header, and written back (temp file, then rename) when the context
//! drops. `SURFEL_PIPELINE_CACHE=0` disables it.

use std::path::PathBuf;

use ash::vk;

/// Size of `VkPipelineCacheHeaderVersionOne`.
const HEADER_BYTES: usize = 32;

/// Where the cache of the device with `props` lives, or `None` when disabled or no cache
/// directory is known.
pub fn path(props: &vk::PhysicalDeviceProperties) -> Option<PathBuf> {
    if std::env::var("SURFEL_PIPELINE_CACHE").is_ok_and(|v| v == "0") {
        return None;
    }
    let base = std::env::var_os("XDG_CACHE_HOME")
        .filter(|d| !d.is_empty())
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".cache")))?;
    let uuid: String = props
        .pipeline_cache_uuid
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect();
    Some(base.join("surfel").join(format!(
        "pipeline-{:04x}-{:04x}-{}-{uuid}.bin",
        props.vendor_id, props.device_id, props.driver_version
    )))
}

/// Whether `bytes` start with a version-one pipeline-cache header for this vendor, device
/// and cache UUID (anything else is ignored rather than handed to the driver).
pub fn header_matches(bytes: &[u8], vendor: u32, device: u32, uuid: &[u8; 16]) -> bool {
    if bytes.len() < HEADER_BYTES {
        return false;
    }
    let word = |i: usize| u32::from_ne_bytes([bytes[i], bytes[i + 1], bytes[i + 2], bytes[i + 3]]);
    word(0) as usize >= HEADER_BYTES
        && word(4) == vk::PipelineCacheHeaderVersion::ONE.as_raw() as u32
        && word(8) == vendor
        && word(12) == device
        && bytes[16..32] == uuid[..]
}

/// The initial contents for the device with `props`: the file's bytes when its header
/// matches, else nothing.
pub fn load(path: Option<&PathBuf>, props: &vk::PhysicalDeviceProperties) -> Vec<u8> {
    path.and_then(|p| std::fs::read(p).ok())
        .filter(|b| {
            header_matches(
                b,
                props.vendor_id,
                props.device_id,
                &props.pipeline_cache_uuid,
            )
        })
        .unwrap_or_default()
}

/// Writes `data` to `path` through a temporary file and a rename, so concurrent writers
/// (processes, or contexts dropped on several threads of one process) never leave a
/// half-written or interleaved cache.
pub fn save(path: &PathBuf, data: &[u8]) -> std::io::Result<()> {
    static SAVES: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir)?;
    }
    let n = SAVES.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let tmp = path.with_extension(format!("tmp{}-{n}", std::process::id()));
    std::fs::write(&tmp, data)?;
    std::fs::rename(&tmp, path)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn header(vendor: u32, device: u32, uuid: [u8; 16]) -> Vec<u8> {
        let mut b = Vec::new();
        b.extend_from_slice(&32u32.to_ne_bytes());
        b.extend_from_slice(&1u32.to_ne_bytes());
        b.extend_from_slice(&vendor.to_ne_bytes());
        b.extend_from_slice(&device.to_ne_bytes());
        b.extend_from_slice(&uuid);
        b.extend_from_slice(&[7; 40]);
        b
    }

    #[test]
    fn only_a_header_for_this_device_is_accepted() {
        let uuid = [3u8; 16];
        let good = header(0x10de, 0x2684, uuid);
        assert!(header_matches(&good, 0x10de, 0x2684, &uuid));
        assert!(
            !header_matches(&good, 0x1002, 0x2684, &uuid),
            "other vendor"
        );
        assert!(
            !header_matches(&good, 0x10de, 0x2685, &uuid),
            "other device"
        );
        assert!(
            !header_matches(&good, 0x10de, 0x2684, &[4; 16]),
            "other driver build"
        );
        assert!(
            !header_matches(&good[..31], 0x10de, 0x2684, &uuid),
            "truncated"
        );
        let mut version = good.clone();
        version[4] = 9;
        assert!(
            !header_matches(&version, 0x10de, 0x2684, &uuid),
            "unknown version"
        );
        let mut size = good.clone();
        size[..4].copy_from_slice(&8u32.to_ne_bytes());
        assert!(
            !header_matches(&size, 0x10de, 0x2684, &uuid),
            "header too small"
        );
        assert!(!header_matches(b"garbage", 0x10de, 0x2684, &uuid));
    }
}
