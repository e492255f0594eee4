//! E57 reader (ASTM E2807), through the `e57` crate.
//!
//! Every scan (`data3D` entry) of the file is read record by record (the crate's raw reader):
//! a valid Cartesian coordinate is used as is, else a valid spherical one is converted
//! (`x = r cos(el) cos(az)`, `y = r cos(el) sin(az)`, `z = r sin(el)`), and each scan's pose
//! (rotation quaternion, then translation) is applied, all in f64. Points with neither (their
//! `cartesianInvalidState` / `sphericalInvalidState` is not 0: a mere direction or no
//! coordinate at all) are skipped and counted in `stats.dropped_invalid`. The f64 bounding-box
//! centre becomes [`Cloud::origin`] and is subtracted before the conversion to f32, as for LAS.
//! Colors are normalized by the scan's color limits (else the color fields' type bounds) to
//! sRGB bytes (points without a valid color in a file that has colors are white); intensity
//! becomes the `intensity` scalar, in the file's units (0 where a point has none). A scan with
//! a pose, or with spherical coordinates (ranges measured from the scanner), records where its
//! scanner stood: the pose's translation becomes that scan's [`Sensor`], which estimated
//! normals face.

use std::fs::File;
use std::io::{BufReader, Read, Seek};
use std::path::Path;

use e57::{E57Reader, PointCloud, RecordDataType, RecordName, RecordValue};
use glam::{DQuat, DVec3, Vec3};

use super::cloud::{Bounds, Cloud, LoadStats, Scalar, Sensor};
use super::error::LoadError;
use super::guard;

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
    let message = describe(&err);
    match scan {
        Some(scan) => LoadError::whole(file, format!("scan {scan}: {message}")),
        None => LoadError::whole(file, message),
    }
}

/// The crate's message, leading with a page checksum failure when there is one: the crate
/// wraps it in "File appears to be truncated", which a corrupt page is not.
fn describe(err: &e57::Error) -> String {
    let text = err.to_string();
    match text.find("Detected invalid checksum") {
        Some(at) => format!("corrupt page: {}", &text[at..]),
        None => text,
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

/// A color channel's value range: the scan's color limits, else its record type's bounds, else
/// 0..1.
fn channel_range(
    pc: &PointCloud,
    limits: Option<(&Option<RecordValue>, &Option<RecordValue>)>,
    field: Option<usize>,
) -> (f64, f64) {
    let value = |v: &Option<RecordValue>| match v {
        Some(RecordValue::Integer(i)) => Some(*i as f64),
        Some(RecordValue::Single(f)) => Some(f64::from(*f)),
        Some(RecordValue::Double(d)) => Some(*d),
        _ => None,
    };
    if let Some((Some(lo), Some(hi))) = limits.map(|(lo, hi)| (value(lo), value(hi))) {
        return (lo, hi);
    }
    match field.map(|k| &pc.prototype[k].data_type) {
        Some(RecordDataType::Integer { min, max }) => (*min as f64, *max as f64),
        Some(RecordDataType::ScaledInteger {
            min,
            max,
            scale,
            offset,
        }) => (*min as f64 * scale + offset, *max as f64 * scale + offset),
        Some(RecordDataType::Single {
            min: Some(lo),
            max: Some(hi),
        }) => (f64::from(*lo), f64::from(*hi)),
        Some(RecordDataType::Double {
            min: Some(lo),
            max: Some(hi),
        }) => (*lo, *hi),
        // Unbounded floating-point colors: taken as 0..1.
        _ => (0.0, 1.0),
    }
}

/// Where a scan's fields are in its records, and how to turn them into points.
struct Scan {
    cartesian: Option<[usize; 3]>,
    cartesian_state: Option<usize>,
    spherical: Option<[usize; 3]>,
    spherical_state: Option<usize>,
    color: Option<[usize; 3]>,
    color_invalid: Option<usize>,
    /// (min, max) of each color channel, mapped to 0..255.
    color_range: [(f64, f64); 3],
    intensity: Option<usize>,
    intensity_invalid: Option<usize>,
    rotation: DQuat,
    translation: DVec3,
    /// Where the scanner stood, in the file's frame: the pose's translation when the scan
    /// has a pose or records ranges (spherical coordinates are measured from the scanner).
    sensor: Option<DVec3>,
}

impl Scan {
    fn new(pc: &PointCloud) -> Scan {
        let find = |name: RecordName| pc.prototype.iter().position(|r| r.name == name);
        let three = |a, b, c| Some([find(a)?, find(b)?, find(c)?]);
        let color = three(
            RecordName::ColorRed,
            RecordName::ColorGreen,
            RecordName::ColorBlue,
        );
        let limits = pc.color_limits.as_ref();
        let channel_limits = [
            limits.map(|l| (&l.red_min, &l.red_max)),
            limits.map(|l| (&l.green_min, &l.green_max)),
            limits.map(|l| (&l.blue_min, &l.blue_max)),
        ];
        let (rotation, translation) =
            pc.transform
                .as_ref()
                .map_or((DQuat::IDENTITY, DVec3::ZERO), |t| {
                    let q = &t.rotation;
                    let d = &t.translation;
                    (
                        DQuat::from_xyzw(q.x, q.y, q.z, q.w),
                        DVec3::new(d.x, d.y, d.z),
                    )
                });
        Scan {
            cartesian: three(
                RecordName::CartesianX,
                RecordName::CartesianY,
                RecordName::CartesianZ,
            ),
            cartesian_state: find(RecordName::CartesianInvalidState),
            spherical: three(
                RecordName::SphericalRange,
                RecordName::SphericalAzimuth,
                RecordName::SphericalElevation,
            ),
            spherical_state: find(RecordName::SphericalInvalidState),
            color,
            color_invalid: find(RecordName::IsColorInvalid),
            color_range: [0, 1, 2]
                .map(|i| channel_range(pc, channel_limits[i], color.map(|c| c[i]))),
            intensity: find(RecordName::Intensity),
            intensity_invalid: find(RecordName::IsIntensityInvalid),
            rotation,
            translation,
            sensor: (pc.transform.is_some()
                || pc
                    .prototype
                    .iter()
                    .any(|r| r.name == RecordName::SphericalRange))
            .then_some(translation),
        }
    }
}

/// One decoded record.
struct Decoded {
    /// World position, `None` for a point the file marks invalid.
    world: Option<DVec3>,
    color: Option<[u8; 4]>,
    intensity: Option<f32>,
}

/// Decodes one record of `scan`.
fn decode(pc: &PointCloud, scan: &Scan, values: &[RecordValue]) -> e57::Result<Decoded> {
    let value = |k: usize| values[k].to_f64(&pc.prototype[k].data_type);
    let flag = |k: Option<usize>| k.map_or(Ok(0.0), value);
    let local = if let (Some([x, y, z]), 0.0) = (scan.cartesian, flag(scan.cartesian_state)?) {
        Some(DVec3::new(value(x)?, value(y)?, value(z)?))
    } else if let (Some([r, a, e]), 0.0) = (scan.spherical, flag(scan.spherical_state)?) {
        let (range, azimuth, elevation) = (value(r)?, value(a)?, value(e)?);
        Some(
            range
                * DVec3::new(
                    elevation.cos() * azimuth.cos(),
                    elevation.cos() * azimuth.sin(),
                    elevation.sin(),
                ),
        )
    } else {
        None
    };
    let world = local.map(|p| scan.rotation * p + scan.translation);
    let color = match (scan.color, flag(scan.color_invalid)?) {
        (Some(rgb), 0.0) => {
            let mut color = [0, 0, 0, 255];
            for (c, (k, (lo, hi))) in color.iter_mut().zip(rgb.into_iter().zip(scan.color_range)) {
                let unit = if hi > lo {
                    (value(k)? - lo) / (hi - lo)
                } else {
                    0.0
                };
                *c = (unit.clamp(0.0, 1.0) * 255.0).round() as u8;
            }
            Some(color)
        }
        _ => None,
    };
    let intensity = match (scan.intensity, flag(scan.intensity_invalid)?) {
        (Some(k), 0.0) => Some(value(k)? as f32),
        _ => None,
    };
    Ok(Decoded {
        world,
        color,
        intensity,
    })
}

/// One valid point of a scan: its position in the file's frame, and its colour and intensity
/// when the scan records them.
pub(crate) struct E57Point {
    /// The scan (`data3D` entry) it belongs to.
    pub scan: usize,
    pub world: DVec3,
    pub color: Option<[u8; 4]>,
    pub intensity: Option<f32>,
}

/// Passes every valid point of every scan of `reader`, a file of `size` bytes, to `sink`; an
/// error from the sink stops the reading. Returns the records declared and those without a
/// valid position.
fn read_scans<R: Read + Seek>(
    file: &str,
    reader: &mut E57Reader<R>,
    sink: &mut dyn FnMut(E57Point) -> Result<(), LoadError>,
) -> Result<(u64, usize), LoadError> {
    let (mut records_declared, mut invalid) = (0u64, 0usize);
    for (index, pc) in reader.pointclouds().iter().enumerate() {
        let scan = Scan::new(pc);
        records_declared = records_declared.saturating_add(pc.records);
        let records = reader
            .pointcloud_raw(pc)
            .map_err(|e| crate_error(file, Some(index), e))?;
        for (i, values) in records.enumerate() {
            let at_record = |e: e57::Error| {
                LoadError::whole(file, format!("scan {index}, record {i}: {}", describe(&e)))
            };
            let values = values.map_err(at_record)?;
            let Decoded {
                world,
                color,
                intensity,
            } = decode(pc, &scan, &values).map_err(at_record)?;
            let Some(world) = world else {
                invalid += 1;
                continue;
            };
            sink(E57Point {
                scan: index,
                world,
                color,
                intensity,
            })?;
        }
    }
    Ok((records_declared, invalid))
}

/// Opens an E57 file after checking its header: the reader, and the file's size.
fn open(path: &Path) -> Result<(E57Reader<BufReader<File>>, u64), LoadError> {
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
    let reader = guard::third_party(|| E57Reader::new(BufReader::new(open)))
        .map_err(|e| LoadError::whole(&file, e))?
        .map_err(|e| crate_error(&file, None, e))?;
    Ok((reader, size))
}

/// Loads an E57 file.
pub fn load(path: &Path) -> Result<Cloud, LoadError> {
    let file = path.display().to_string();
    let (mut reader, size) = open(path)?;
    let mut points = Points::default();
    let mut scanners = Vec::new();
    for pc in reader.pointclouds() {
        let scan = Scan::new(&pc);
        scanners.push(scan.sensor);
        points.any_color |= scan.color.is_some();
        points.any_intensity |= scan.intensity.is_some();
        // The declared count bounds the reservation only as far as the file can hold it.
        let reserve = usize::try_from(pc.records.min(size / 4)).unwrap_or(0);
        points.world.reserve(reserve);
    }
    // The first point of each scan that has any, and the scan.
    let mut starts: Vec<(usize, usize)> = Vec::new();
    let mut sink = |p: E57Point| {
        if starts.last().is_none_or(|&(_, scan)| scan != p.scan) {
            starts.push((points.world.len(), p.scan));
        }
        points.world.push(p.world);
        points.colors.push(p.color.unwrap_or(NO_COLOR));
        points.intensity.push(p.intensity.unwrap_or(0.0));
        Ok(())
    };
    let (records, invalid) = guard::third_party(|| read_scans(&file, &mut reader, &mut sink))
        .map_err(|e| LoadError::whole(&file, e))??;
    points.records = records;
    points.invalid = invalid;
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
        sensors: if scanners.iter().any(Option::is_some) {
            starts
                .iter()
                .map(|&(first, scan)| Sensor {
                    first,
                    // A scan without a scanner position orients its normals by propagation.
                    position: scanners[scan].map_or(Vec3::NAN, |s| (s - origin).as_vec3()),
                })
                .collect()
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
