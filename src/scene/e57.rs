//! E57 reader (ASTM E2807), through the `e57` crate.
//!
//! Every scan (`data3D` entry) of the file is read: spherical coordinates are converted to
//! Cartesian (`x = r cos(el) cos(az)`, `y = r cos(el) sin(az)`, `z = r sin(el)`) and each
//! scan's pose (rotation quaternion and translation) is applied, all in f64. Points the file
//! marks invalid (`cartesianInvalidState` or `sphericalInvalidState` other than 0, i.e. a mere
//! direction or no coordinate at all) are skipped and counted in `stats.dropped_invalid`. The
//! f64 bounding-box centre becomes [`Cloud::origin`] and is subtracted before the conversion to
//! f32, as for LAS. Colors are normalized by the scan's color limits to sRGB bytes (points
//! without a valid color in a file that has colors are white); intensity becomes the
//! `intensity` scalar, in the file's units (0 where a point has none).

use std::fs::File;
use std::io::{BufReader, Read, Seek};
use std::path::Path;

use e57::{CartesianCoordinate, E57Reader};
use glam::DVec3;

use super::cloud::{Bounds, Cloud, LoadStats, Scalar};
use super::error::LoadError;

/// Bytes of the E57 file header (signature, version, lengths, XML offset, page size).
const HEADER_BYTES: usize = 48;

/// Color of a point without a valid color in a file where other points have one.
const NO_COLOR: [u8; 4] = [255, 255, 255, 255];

/// Checks that the XML section the header points to lies inside a file of `size` bytes, so a
/// corrupt header fails with its offset before anything is allocated for it.
fn check_header(file: &str, header: &[u8; HEADER_BYTES], size: u64) -> Result<(), LoadError> {
    if &header[..8] != b"ASTM-E57" {
        return Err(LoadError::at_byte(
            file,
            0,
            "expected the E57 signature \"ASTM-E57\"",
        ));
    }
    let word = |at: usize| {
        let mut raw = [0u8; 8];
        raw.copy_from_slice(&header[at..at + 8]);
        u64::from_le_bytes(raw)
    };
    let (xml_offset, xml_length) = (word(24), word(32));
    if xml_offset.saturating_add(xml_length) > size {
        return Err(LoadError::at_byte(
            file,
            24,
            format!(
                "the XML section ({xml_length} bytes at byte {xml_offset}) ends past the end of the file at byte {size} (truncated file?)"
            ),
        ));
    }
    Ok(())
}

/// The error for a failure the `e57` crate reports (its message names the page for checksum
/// errors).
fn crate_error(file: &str, scan: Option<usize>, err: e57::Error) -> LoadError {
    match scan {
        Some(scan) => LoadError::whole(file, format!("scan {scan}: {err}")),
        None => LoadError::whole(file, err.to_string()),
    }
}

/// Decoded points of all scans, before the origin is known.
#[derive(Default)]
struct Points {
    world: Vec<DVec3>,
    colors: Vec<[u8; 4]>,
    intensity: Vec<f32>,
    any_color: bool,
    any_intensity: bool,
    invalid: usize,
    records: u64,
}

/// A normalized (0..1) color channel as an sRGB byte.
fn channel(v: f32) -> u8 {
    (v.clamp(0.0, 1.0) * 255.0).round() as u8
}

/// Reads every scan of `reader`, a file of `size` bytes.
fn read_scans<R: Read + Seek>(
    file: &str,
    reader: &mut E57Reader<R>,
    size: u64,
) -> Result<Points, LoadError> {
    let mut out = Points::default();
    for (index, pc) in reader.pointclouds().iter().enumerate() {
        out.records = out.records.saturating_add(pc.records);
        out.any_color |= pc.has_color();
        out.any_intensity |= pc.has_intensity();
        // The declared count bounds the reservation only as far as the file can hold it.
        let reserve = usize::try_from(pc.records.min(size / 4)).unwrap_or(0);
        out.world.reserve(reserve);
        let mut points = reader
            .pointcloud_simple(pc)
            .map_err(|e| crate_error(file, Some(index), e))?;
        points.spherical_to_cartesian(true);
        points.apply_pose(true);
        points.intensity_to_color(false);
        points.normalize_intensity(false);
        points.normalize_color(true);
        for point in points {
            let point = point.map_err(|e| crate_error(file, Some(index), e))?;
            let CartesianCoordinate::Valid { x, y, z } = point.cartesian else {
                out.invalid += 1;
                continue;
            };
            out.world.push(DVec3::new(x, y, z));
            out.colors.push(point.color.map_or(NO_COLOR, |c| {
                [channel(c.red), channel(c.green), channel(c.blue), 255]
            }));
            out.intensity.push(point.intensity.unwrap_or(0.0));
        }
    }
    Ok(out)
}

/// Loads an E57 file.
pub fn load(path: &Path) -> Result<Cloud, LoadError> {
    let file = path.display().to_string();
    let io = |source| LoadError::Io {
        file: file.clone(),
        source,
    };
    let mut open = File::open(path).map_err(io)?;
    let size = open.metadata().map_err(io)?.len();
    let mut header = [0u8; HEADER_BYTES];
    if open.read_exact(&mut header).is_err() {
        return Err(LoadError::whole(
            &file,
            format!("the file ends at byte {size}, inside the {HEADER_BYTES}-byte E57 header"),
        ));
    }
    check_header(&file, &header, size)?;
    open.rewind().map_err(io)?;
    let mut reader =
        E57Reader::new(BufReader::new(open)).map_err(|e| crate_error(&file, None, e))?;
    let points = read_scans(&file, &mut reader, size)?;
    let bounds = points.world.iter().fold(Bounds::EMPTY, |mut b, p| {
        b.add(*p);
        b
    });
    let origin = bounds.centre().unwrap_or(DVec3::ZERO);
    let mut cloud = Cloud {
        positions: points
            .world
            .iter()
            .map(|p| (*p - origin).as_vec3())
            .collect(),
        colors: points.any_color.then_some(points.colors),
        scalars: if points.any_intensity {
            vec![Scalar {
                name: "intensity".into(),
                values: points.intensity,
            }]
        } else {
            Vec::new()
        },
        origin,
        stats: LoadStats {
            records: usize::try_from(points.records).unwrap_or(usize::MAX),
            dropped_invalid: points.invalid,
            ..LoadStats::default()
        },
        ..Cloud::default()
    };
    cloud.retain_finite();
    Ok(cloud)
}
