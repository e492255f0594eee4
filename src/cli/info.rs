//! `surfel info`: what a file holds (points, attributes, fields, bounds, load statistics).

use std::path::PathBuf;

use anyhow::Result;
use clap::Args;
use glam::DVec3;

use super::{context, parse_up, InputArgs};
use crate::color;
use crate::scene::camera::Up;
use crate::scene::cloud::LasSummary;
use crate::scene::load_prepared;

#[derive(Args, Debug)]
pub struct InfoArgs {
    pub file: PathBuf,
    /// Skip the GPU capability report.
    #[arg(long)]
    pub no_device: bool,
    /// The axis pointing up in the data (x, y, z, -x, -y, -z). Default: the format's.
    #[arg(long, value_name = "AXIS", allow_hyphen_values = true, value_parser = parse_up)]
    pub up: Option<Up>,
    #[command(flatten)]
    pub input: InputArgs,
    #[command(flatten)]
    pub http: HttpArgs,
}

/// Reading a `.vpc` over HTTP.
#[derive(Args, Debug)]
pub struct HttpArgs {
    /// A `.vpc` URL: requests in flight at most.
    #[arg(long, value_name = "N", default_value_t = crate::source::DEFAULT_CONNECTIONS as u64,
          value_parser = clap::value_parser!(u64).range(1..=256))]
    pub http_connections: u64,
}

/// `surfel info` of a virtual point cloud: its tiles as the `.vpc` lists them (no tile is
/// read), total points, bounds and CRS.
fn info_vpc(location: &str, http: &HttpArgs) -> Result<()> {
    let options = crate::source::HttpOptions {
        connections: http.http_connections as usize,
        ..Default::default()
    };
    let vpc = crate::copc::vpc::read(location, &options)?;
    println!("file              {location}");
    println!("format            virtual point cloud (STAC ItemCollection)");
    println!("tiles             {}", vpc.tiles.len());
    println!("points            {}", vpc.points());
    match vpc.bounds() {
        Some((lo, hi)) => println!(
            "bounds            {:.3} {:.3} {:.3} .. {:.3} {:.3} {:.3}",
            lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]
        ),
        None => println!("bounds            unknown (no tile has a 3D proj:bbox)"),
    }
    let mut crs: Vec<String> = vpc
        .tiles
        .iter()
        .map(|t| match &t.crs {
            Some(c) => match (c.epsg, &c.wkt2) {
                (Some(code), _) => format!("EPSG:{code}"),
                (None, Some(_)) => "WKT 2 without an EPSG code".to_owned(),
                (None, None) => "none".to_owned(),
            },
            None => "none".to_owned(),
        })
        .collect();
    crs.sort();
    crs.dedup();
    println!("crs               {}", crs.join(", "));
    for t in &vpc.tiles {
        let bounds = t.bounds.map_or("bounds unknown".to_owned(), |(lo, hi)| {
            format!(
                "{:.3} {:.3} {:.3} .. {:.3} {:.3} {:.3}",
                lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]
            )
        });
        println!(
            "  {:<24} {:>12} points  {}  {}  {bounds}",
            t.id,
            t.points,
            t.encoding.media_type(),
            t.href
        );
    }
    Ok(())
}

pub(super) fn info(a: InfoArgs) -> Result<()> {
    let name = a.file.to_string_lossy();
    if crate::copc::vpc::is_vpc(&name) {
        return info_vpc(&name, &a.http);
    }
    let cloud = load_prepared(&a.file, &a.input.options(false))?;
    println!("file              {}", a.file.display());
    println!("points            {}", cloud.len());
    println!("records in file   {}", cloud.stats.records);
    println!("dropped (NaN/inf) {}", cloud.stats.dropped_non_finite);
    println!("dropped (invalid) {}", cloud.stats.dropped_invalid);
    let duplicates = cloud.duplicates();
    println!(
        "duplicates        {} points at {} distinct positions",
        duplicates.points, duplicates.positions
    );
    if let Some(columns) = &cloud.stats.guessed_columns {
        println!("columns guessed   {columns} (from their count; name them with a first row or --columns)");
    }
    if let Some(levels) = &cloud.stats.levels {
        let per_level: Vec<String> = levels.points.iter().map(u64::to_string).collect();
        println!(
            "octree levels     read {} of {} (points per level: {}); {} points skipped",
            levels.read,
            levels.points.len(),
            per_level.join(", "),
            levels.points_skipped()
        );
    }
    println!(
        "faces             {}",
        cloud.faces.as_ref().map_or(0, |f| f.len())
    );
    let mut attrs = vec!["position"];
    attrs.extend(cloud.normals.as_ref().map(|_| "normal"));
    attrs.extend(cloud.colors.as_ref().map(|_| "color"));
    attrs.extend(cloud.radii.as_ref().map(|_| "radius"));
    let scalars: Vec<&str> = cloud.scalars.iter().map(|s| s.name.as_str()).collect();
    attrs.extend(scalars);
    println!("attributes        {}", attrs.join(", "));
    if !cloud.scalars.is_empty() {
        println!("scalar fields     min .. max (2nd .. 98th percentile)");
        for s in &cloud.scalars {
            let (min, max) = color::min_max(&s.values);
            let [lo, hi] = color::robust_range(&s.values);
            println!("  {:<22} {min} .. {max} ({lo} .. {hi})", s.name);
        }
    }
    if let Some(origin) = cloud.stats.gps_time_origin {
        println!(
            "gps_time origin   {origin:.6} s (the earliest; gps_time counts seconds after it)"
        );
    }
    let mut fields = color::fields(&cloud);
    let normals = match (&cloud.normals, &cloud.radii, a.input.k) {
        (Some(_), Some(_), _) => "from the file".to_owned(),
        (_, _, 0) => "none (--k 0)".to_owned(),
        _ => {
            if cloud.normals.is_none() {
                let at = fields
                    .iter()
                    .position(|f| f == "elevation")
                    .map_or(0, |i| i + 1);
                fields.insert(at, "normal".to_owned());
            }
            format!(
                "estimated (k = {}) for the methods that read them and for --color-by normal",
                a.input.k
            )
        }
    };
    println!("normals, radii    {normals}");
    if cloud.normals.is_none() && a.input.k > 0 {
        println!(
            "normal signs      {}",
            crate::scene::orient::Rule::for_cloud(&cloud).describe()
        );
    }
    println!("color by          {}", fields.join(", "));
    if let Some((lo, hi)) = cloud.bounds() {
        let o = cloud.origin;
        println!("origin            {:.3} {:.3} {:.3}", o.x, o.y, o.z);
        println!("bounds (local)    {lo:.6} .. {hi:.6}");
    }
    if let Some(las) = &cloud.stats.las {
        print_las(las, cloud.stats.file_bounds);
    }
    let (up, source) = match a.up {
        Some(up) => (up, "--up"),
        None => (
            cloud.up,
            cloud.stats.up_rule.as_deref().unwrap_or("format default"),
        ),
    };
    println!("up axis           {} ({source})", up.name());
    let n = cloud.len() as u64;
    let streams = crate::point_streams::StreamLayout::streams_for(&cloud, None);
    let mut total = 0;
    println!("GPU streams       bytes/point  MiB");
    for s in streams {
        let bytes = crate::point_streams::StreamLayout::stream_bytes(s, n);
        total += bytes;
        println!(
            "  {:<22} {:>5}  {:>9.2}",
            s.name(),
            s.bytes_per_point(),
            bytes as f64 / (1 << 20) as f64
        );
    }
    if !cloud.scalars.is_empty() {
        println!(
            "  {:<22} {:>5}  (the field colored by, when one is)",
            "scalar f32", 4
        );
    }
    let batches = n.div_ceil(u64::from(crate::layout::BATCH_POINTS));
    println!(
        "GPU memory        {:.2} bytes/point, {:.2} MiB in {batches} batches of {} points",
        total as f64 / n.max(1) as f64,
        total as f64 / (1 << 20) as f64,
        crate::layout::BATCH_POINTS
    );
    if !a.no_device {
        let ctx = context(false)?;
        println!("{}", ctx.caps);
    }
    Ok(())
}

/// The LAS header's lines of `surfel info`: version, point format, scale, offset, CRS and the
/// file-coordinate bounds (`bounds`), with as many decimals as the scale has.
fn print_las(las: &LasSummary, bounds: Option<[DVec3; 2]>) {
    let [s, o] = [las.scale, las.offset];
    println!(
        "LAS               version {}, point format {}",
        las.version, las.point_format
    );
    println!("scale             {} {} {}", s.x, s.y, s.z);
    println!("offset            {} {} {}", o.x, o.y, o.z);
    println!("CRS               {}", las.crs.as_deref().unwrap_or("none"));
    if let Some([lo, hi]) = bounds {
        let finest = s.min_element();
        let decimals = if finest > 0.0 && finest.is_finite() {
            (-finest.log10()).ceil().clamp(0.0, 9.0) as usize
        } else {
            3
        };
        let p = |v: DVec3| format!("{:.decimals$} {:.decimals$} {:.decimals$}", v.x, v.y, v.z);
        println!("bounds (file)     {} .. {}", p(lo), p(hi));
    }
    if let Some(note) = &las.note {
        println!("note              {note}");
    }
}
