//! `surfel convert` against its compressor: the points of a LAS file converted to COPC, and the
//! same point records compressed to plain LAZ by the `laz` crate (laz-rs, which Python's lazrs
//! wraps) on one thread and on all, so the converter's rate reads beside the compressor's own.
//!
//! `SURFEL_CONVERT_INPUT` names a LAS file (point format 6 or 7); without it the dragon is
//! sampled to `SURFEL_CONVERT_POINTS` points (default 2 M) and written as a format-6 LAS file.
//! `SURFEL_DATA` overrides the data folder (default `../shared/data` beside the crate).

use std::io::Cursor;
use std::path::PathBuf;
use std::time::Instant;

use surfel::copc::convert::{self, ConvertOptions};
use surfel::scene::{self, sample};

fn data(rel: &str) -> PathBuf {
    let root = std::env::var_os("SURFEL_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/data"));
    root.join(rel)
}

/// A format-6 LAS file of the dragon sampled to `n` points, scaled to metres on a UTM grid.
fn sampled_las(n: usize, path: &std::path::Path) {
    let dragon = scene::load(&data("stanford/dragon_vrip.ply")).expect("dragon");
    let cloud = sample::sample_mesh(&dragon, n, 1).expect("sampling");
    let mut header = las::Builder::from((1, 4));
    header.point_format = las::point::Format::new(6).expect("format 6");
    header.transforms = las::Vector {
        x: las::Transform {
            scale: 0.001,
            offset: 500_000.0,
        },
        y: las::Transform {
            scale: 0.001,
            offset: 4_000_000.0,
        },
        z: las::Transform {
            scale: 0.001,
            offset: 0.0,
        },
    };
    let header = header.into_header().expect("header");
    let mut writer = las::Writer::from_path(path, header).expect("writer");
    for (i, p) in cloud.positions.iter().enumerate() {
        let w = p.as_dvec3() * 1000.0 + cloud.origin;
        writer
            .write_point(las::Point {
                x: w.x + 500_000.0,
                y: w.y + 4_000_000.0,
                z: w.z + 100.0,
                intensity: (i % 997) as u16,
                return_number: 1,
                number_of_returns: 1,
                gps_time: Some(1e8 + i as f64 * 1e-5),
                ..las::Point::default()
            })
            .expect("write");
    }
    writer.close().expect("close");
}

fn rate(points: usize, seconds: f64) -> f64 {
    points as f64 / seconds / 1e6
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() {
    let dir = std::env::temp_dir().join(format!("surfel-bench-convert-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("scratch folder");
    let input = std::env::var_os("SURFEL_CONVERT_INPUT").map_or_else(
        || {
            let n = std::env::var("SURFEL_CONVERT_POINTS")
                .ok()
                .and_then(|v| v.parse().ok())
                .unwrap_or(2_000_000);
            let path = dir.join("sampled.las");
            sampled_las(n, &path);
            path
        },
        PathBuf::from,
    );
    let out = dir.join("out.copc.laz");
    let runs = 3;
    let mut convert_s = Vec::new();
    let mut stats = None;
    for _ in 0..runs {
        let start = Instant::now();
        stats = Some(convert::convert(&input, &out, &ConvertOptions::default()).expect("convert"));
        convert_s.push(start.elapsed().as_secs_f64());
    }
    let stats = stats.expect("one run");
    let points = stats.points as usize;

    let bytes = std::fs::read(&input).expect("input");
    let header = las::Reader::from_path(&input)
        .expect("LAS")
        .header()
        .clone();
    let format = header.point_format();
    let at = u32::from_le_bytes(bytes[96..100].try_into().expect("offset")) as usize;
    let records = &bytes[at..at + points * usize::from(format.len())];
    let items = laz::LazItemRecordBuilder::default_for_point_format_id(
        format.to_u8().expect("format"),
        format.extra_bytes,
    )
    .expect("items");
    let vlr = laz::LazVlrBuilder::new(items).build();
    let mut one_s = Vec::new();
    let mut all_s = Vec::new();
    let mut laz_bytes = 0;
    for _ in 0..runs {
        let mut sink = Cursor::new(Vec::new());
        let start = Instant::now();
        laz::compress_buffer(&mut sink, records, vlr.clone()).expect("compress");
        one_s.push(start.elapsed().as_secs_f64());
        let mut sink = Cursor::new(Vec::new());
        let start = Instant::now();
        laz::par_compress_buffer(&mut sink, records, &vlr).expect("compress");
        all_s.push(start.elapsed().as_secs_f64());
        laz_bytes = sink.into_inner().len();
    }
    let threads = rayon::current_num_threads();
    let (c, one, all) = (median(convert_s), median(one_s), median(all_s));
    println!(
        "{points} points of {} (format {}), {threads} threads, median of {runs}:",
        input.display(),
        format.to_u8().unwrap_or(0)
    );
    println!(
        "  surfel convert to COPC   {c:6.2} s  {:5.2} M points/s  {:5.1} bytes/point  ({} nodes)",
        rate(points, c),
        stats.bytes as f64 / points as f64,
        stats.nodes
    );
    println!(
        "  laz-rs to LAZ, 1 thread  {one:6.2} s  {:5.2} M points/s  {:5.1} bytes/point",
        rate(points, one),
        laz_bytes as f64 / points as f64
    );
    println!(
        "  laz-rs to LAZ, parallel  {all:6.2} s  {:5.2} M points/s",
        rate(points, all)
    );
    std::fs::remove_dir_all(&dir).expect("remove the scratch folder");
}
