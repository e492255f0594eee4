//! Bounded resources: files of every format whose counts claim 10¹² elements are refused (or
//! read for what they hold) while the loader's peak heap stays within a fixed multiple of the
//! file's size plus a constant, measured by a counting allocator.

mod common;

use std::alloc::{GlobalAlloc, Layout, System};
use std::io::Cursor;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;

use surfel::scene;

/// Bytes allocated now, and the most since the last [`peak_of`] started.
static CURRENT: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);

struct Peak;

fn grew(bytes: usize) {
    let now = CURRENT.fetch_add(bytes, Ordering::SeqCst) + bytes;
    PEAK.fetch_max(now, Ordering::SeqCst);
}

// SAFETY: every call is forwarded unchanged to the system allocator; the bookkeeping touches
// only atomics, which do not allocate.
unsafe impl GlobalAlloc for Peak {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        grew(layout.size());
        // SAFETY: forwarded with the caller's layout.
        unsafe { System.alloc(layout) }
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        grew(layout.size());
        // SAFETY: forwarded with the caller's layout.
        unsafe { System.alloc_zeroed(layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        grew(new_size);
        CURRENT.fetch_sub(layout.size(), Ordering::SeqCst);
        // SAFETY: `ptr` was allocated by `System` (through this allocator) with `layout`.
        unsafe { System.realloc(ptr, layout, new_size) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        CURRENT.fetch_sub(layout.size(), Ordering::SeqCst);
        // SAFETY: `ptr` was allocated by `System` (through this allocator) with `layout`.
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static ALLOCATOR: Peak = Peak;

/// One measurement at a time: the tests of this binary run on parallel threads.
static SERIAL: Mutex<()> = Mutex::new(());

/// The loader may hold this many times the file's bytes at once.
const FACTOR: usize = 64;
/// Plus this much: thread pools, tables, messages.
const CONSTANT: usize = 8 << 20;

const TERA: u64 = 1_000_000_000_000;

fn data(rel: &str) -> Vec<u8> {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../shared/data")
        .join(rel);
    std::fs::read(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

fn file(name: &str, bytes: &[u8]) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("surfel-bounded-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(name);
    std::fs::write(&path, bytes).unwrap();
    path
}

/// Loads `bytes` as `name`, asserting the peak heap bound; the error message, or `None` when
/// the file loaded.
fn load(name: &str, bytes: &[u8]) -> Option<String> {
    let path = file(name, bytes);
    let _serial = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let base = CURRENT.load(Ordering::SeqCst);
    PEAK.store(base, Ordering::SeqCst);
    let result = scene::load(&path);
    let peak = PEAK.load(Ordering::SeqCst) - base;
    let bound = FACTOR * bytes.len() + CONSTANT;
    println!(
        "{name}: peak {peak} bytes for a file of {} bytes",
        bytes.len()
    );
    assert!(
        peak <= bound,
        "{name}: {peak} bytes at the peak for a file of {} bytes (bound {bound})",
        bytes.len()
    );
    result.err().map(|e| {
        let message = e.to_string();
        assert!(
            message.starts_with(&path.display().to_string()),
            "{message}"
        );
        message
    })
}

/// Loads `bytes` as `name` and returns the error, which must name `expected`.
fn refused(name: &str, bytes: &[u8], expected: &str) {
    let message = load(name, bytes).unwrap_or_else(|| panic!("{name} loaded"));
    assert!(message.contains(expected), "{message}");
}

fn patched(mut bytes: Vec<u8>, at: usize, value: u64, len: usize) -> Vec<u8> {
    bytes[at..at + len].copy_from_slice(&value.to_le_bytes()[..len]);
    bytes
}

#[test]
fn ply_claiming_a_tera_vertices() {
    for format in ["ascii", "binary_little_endian", "binary_big_endian"] {
        let text = format!(
            "ply\nformat {format} 1.0\nelement vertex {TERA}\nproperty float x\nproperty float y\nproperty float z\nelement face {TERA}\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n"
        );
        refused("tera.ply", text.as_bytes(), "1000000000000");
    }
}

#[test]
fn pcd_claiming_a_tera_points_or_values() {
    for data in ["ascii", "binary", "binary_compressed"] {
        let points = format!(
            "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 1\nHEIGHT 1\nPOINTS {TERA}\nDATA {data}\n0 0 0\n"
        );
        refused("points.pcd", points.as_bytes(), "DATA size mismatch");
        let count = format!(
            "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 {TERA}\nWIDTH 1\nHEIGHT 1\nPOINTS 1\nDATA {data}\n0 0 0\n"
        );
        refused("count.pcd", count.as_bytes(), "DATA size mismatch");
    }
}

/// A LAS 1.4 file of 50 points in format 6, compressed or not.
fn las14(compressed: bool) -> Vec<u8> {
    let mut builder = las::Builder::from((1, 4));
    builder.point_format = las::point::Format::new(6).unwrap();
    builder.point_format.is_compressed = compressed;
    let mut writer =
        las::Writer::new(Cursor::new(Vec::new()), builder.into_header().unwrap()).unwrap();
    for i in 0..50 {
        writer
            .write_point(las::Point {
                x: i as f64,
                y: (i * 7 % 13) as f64,
                z: 1.0,
                gps_time: Some(i as f64),
                ..Default::default()
            })
            .unwrap();
    }
    writer.close().unwrap();
    writer.into_inner().unwrap().into_inner()
}

#[test]
fn las_and_laz_claiming_a_tera_points() {
    for (name, compressed) in [("tera.las", false), ("tera.laz", true)] {
        // The 64-bit point count of LAS 1.4 (byte 247); the legacy 32-bit one (107) is 0.
        let bytes = patched(patched(las14(compressed), 247, TERA, 8), 107, 0, 4);
        assert!(load(name, &bytes).is_some(), "{name} loaded");
        // As many VLRs (byte 100) as 32 bits hold.
        let bytes = patched(las14(compressed), 100, u64::from(u32::MAX), 4);
        refused(name, &bytes, "the header declares 4294967295 VLRs");
    }
    let laz = data("lidar/autzen_trim.laz");
    // The chunk table's chunk count (4 bytes after its version) set to 2^32 - 1.
    let table = i64::from_le_bytes(laz[2144..2152].try_into().unwrap()) as usize;
    let bytes = patched(laz, table + 4, u64::from(u32::MAX), 4);
    refused("chunks.laz", &bytes, "4294967295 chunks for 110000 points");
}

#[test]
fn copc_claiming_a_tera_points() {
    let whole = data("copc/1.2-with-color.copc.laz");
    let bytes = patched(patched(whole.clone(), 107, 0, 4), 247, TERA, 8);
    refused("tera.copc.laz", &bytes, "declares 1000000000000 points");
    // The root node's hierarchy entry claiming a tera points.
    let bytes = patched(whole, 31_632, u64::from(i32::MAX as u32), 4);
    refused("node.copc.laz", &bytes, "cannot hold the 2147483647 points");
}

#[test]
fn e57_claiming_a_tera_records() {
    // The scan's recordCount raised from 30,571 to 10^12.
    let bytes = common::bunny_e57_claiming(TERA);
    refused("tera.e57", &bytes, "scan 0, record 30571: ");
}

#[test]
fn obj_and_text_claiming_a_tera_elements() {
    let obj = format!("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 {TERA}\n");
    refused(
        "tera.obj",
        obj.as_bytes(),
        "face index 1000000000000 is out of range",
    );
    // A `.pts` count line is a claim the reader does not act on: the points are what is there.
    let pts = format!("{TERA}\n0 0 0 10 1 2 3\n");
    assert_eq!(load("tera.pts", pts.as_bytes()), None);
}

#[test]
fn the_measure_sees_a_loader_allocate() {
    // The bound must be able to fail: a 1,000-line text file makes vectors of its values.
    let text: String = (0..1000).map(|i| format!("{i} 0 0\n")).collect();
    let _serial = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let base = CURRENT.load(Ordering::SeqCst);
    PEAK.store(base, Ordering::SeqCst);
    let cloud = scene::load(&file("count.xyz", text.as_bytes())).expect("loads");
    let peak = PEAK.load(Ordering::SeqCst) - base;
    assert!(
        peak >= 1000 * 3 * 8,
        "{peak} bytes for {} points",
        cloud.len()
    );
}
