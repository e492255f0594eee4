//! LAS point records for the COPC writer: the records of any LAS point format re-encoded as
//! point format 6 or 7 (what a COPC file holds), and a cloud's columns encoded as records.
//!
//! A cloud's normals are stored compactly as two 16-bit octahedral coordinates
//! ([`crate::scene::octahedral`]) and its radii as a 16-bit integer with the extra-bytes scale and offset
//! (any LAS 1.4 reader gets the radius back from them); other scalar fields are f32.

use glam::{DVec3, Vec3};

use super::copc_write::{base_len, Layout, RawVlr};
use crate::scene::octahedral::{octahedral, unorm16, NORMAL_OCT};
use crate::scene::Cloud;

/// The names of the standard LAS fields among a cloud's scalars (as the loaders name them).
const STANDARD: [&str; 6] = [
    "intensity",
    "classification",
    "return_number",
    "number_of_returns",
    "point_source_id",
    "gps_time",
];

/// Extra-bytes name of the splat radius.
pub const RADIUS_NAME: &str = "radius";

/// The radius is stored in 16 bits (scale and offset over the cloud's range) when its largest
/// value is at most this many times its smallest: the step, (max − min) / 65,535, is then
/// within 0.5 % of the smallest radius, half of it the largest rounding error. Wider ranges
/// are stored as f32.
const RADIUS_RANGE_16: f32 = 600.0;

/// The 192-byte extra-bytes descriptor (LAS 1.4 R15 table 24) of a field of `data_type`
/// named `name` (at most 31 bytes kept), with a scale and offset when given.
fn descriptor(name: &str, data_type: u8, scale: Option<(f64, f64)>) -> [u8; 192] {
    let mut d = [0u8; 192];
    d[2] = data_type;
    let bytes = name.as_bytes();
    let n = bytes.len().min(31);
    d[4..4 + n].copy_from_slice(&bytes[..n]);
    if let Some((scale, offset)) = scale {
        d[3] = 0b1_1000;
        d[112..120].copy_from_slice(&scale.to_le_bytes());
        d[136..144].copy_from_slice(&offset.to_le_bytes());
    }
    d
}

/// The smallest power of ten at least `extent / 2^30`, so coordinates measured from the
/// lower corner fit 30 bits (1e-9 for an empty or degenerate extent).
pub fn decimal_scale(extent: f64) -> f64 {
    let raw = extent / f64::from(1u32 << 30);
    if raw.is_finite() && raw > 0.0 {
        10f64.powf(raw.log10().ceil())
    } else {
        1e-9
    }
}

/// The factor taking `cloud`'s intensities to LAS's 16 bits: 65,535 when they are fractions
/// within 0..1 (E57 and normalised text files), else 1 (already counts).
fn intensity_scale(cloud: &Cloud) -> f32 {
    let Some(values) = cloud
        .scalars
        .iter()
        .find(|s| s.name == "intensity")
        .map(|s| &s.values)
    else {
        return 1.0;
    };
    let fractions =
        values.iter().all(|v| (0.0..=1.0).contains(v)) && values.iter().any(|v| v.fract() != 0.0);
    if fractions {
        65535.0
    } else {
        1.0
    }
}

/// How a cloud's radii are stored.
#[derive(Clone, Copy)]
enum RadiusCode {
    /// `(r − offset) / scale` in 16 bits.
    Scaled {
        scale: f64,
        offset: f64,
    },
    Float,
}

/// `cloud` as point records: point format 7 with colours, else 6; coordinates quantized at
/// the finest decimal scale that keeps the cloud's largest extent within 2^30 steps (so they
/// keep their f32 precision), from its lower corner; colours as 16-bit values (times 257);
/// intensity, classification, returns, point source and GPS time in their fields; then as
/// extra bytes the normal ([`NORMAL_OCT`]), the radius ([`RADIUS_NAME`]) and every other
/// scalar field (f32).
pub fn encode_cloud(cloud: &Cloud) -> anyhow::Result<(Layout, Vec<u8>)> {
    use rayon::prelude::*;
    let (lo, hi) = cloud.bounds().unwrap_or((Vec3::ZERO, Vec3::ZERO));
    let scale = decimal_scale(f64::from((hi - lo).max_element()));
    let offset = cloud.origin + lo.as_dvec3();
    let standard = STANDARD.map(|name| {
        cloud
            .scalars
            .iter()
            .find(|s| s.name == name)
            .map(|s| s.values.as_slice())
    });
    let others: Vec<_> = cloud
        .scalars
        .iter()
        .filter(|s| !STANDARD.contains(&s.name.as_str()))
        .collect();
    let mut descriptors = Vec::new();
    if cloud.normals.is_some() {
        descriptors.extend(NORMAL_OCT.map(|n| descriptor(n, 3, None)));
    }
    let radius = cloud.radii.as_ref().map(|radii| {
        let (min, max) = radii
            .iter()
            .fold((f32::INFINITY, 0f32), |(a, b), &r| (a.min(r), b.max(r)));
        if min > 0.0 && max <= min * RADIUS_RANGE_16 {
            let scale = (f64::from(max - min) / 65535.0).max(f64::from(min) * 1e-9);
            RadiusCode::Scaled {
                scale,
                offset: f64::from(min),
            }
        } else {
            RadiusCode::Float
        }
    });
    match radius {
        Some(RadiusCode::Scaled { scale, offset }) => {
            descriptors.push(descriptor(RADIUS_NAME, 3, Some((scale, offset))));
        }
        Some(RadiusCode::Float) => descriptors.push(descriptor(RADIUS_NAME, 9, None)),
        None => {}
    }
    descriptors.extend(others.iter().map(|s| descriptor(&s.name, 9, None)));
    let extra = 4 * cloud.normals.is_some() as usize
        + match radius {
            Some(RadiusCode::Scaled { .. }) => 2,
            Some(RadiusCode::Float) => 4,
            None => 0,
        }
        + 4 * others.len();
    let extra_bytes = u16::try_from(extra)
        .ok()
        .filter(|&b| b < u16::MAX - 64)
        .ok_or_else(|| {
            anyhow::anyhow!("{} extra fields: too many for a LAS record", others.len())
        })?;
    let layout = Layout {
        format: if cloud.colors.is_some() { 7 } else { 6 },
        extra_bytes,
        descriptors,
        scale: DVec3::splat(scale),
        offset,
        vlrs: Vec::new(),
        standard_gps_time: false,
    };
    let len = layout.record_len();
    let base = base_len(layout.format);
    let intensity = intensity_scale(cloud);
    let gps_origin = cloud.stats.gps_time_origin.unwrap_or(0.0);
    let mut records = vec![0u8; cloud.len() * len];
    records
        .par_chunks_exact_mut(len)
        .enumerate()
        .for_each(|(i, r)| {
            let value = |k: usize| standard[k].map_or(0.0, |v| v[i]);
            let byte = |k: usize| value(k).clamp(0.0, 255.0) as u8;
            let p = cloud.origin + cloud.positions[i].as_dvec3() - offset;
            for axis in 0..3 {
                let q = (p[axis] / scale).round() as i32;
                r[4 * axis..4 * axis + 4].copy_from_slice(&q.to_le_bytes());
            }
            let level = (value(0) * intensity).clamp(0.0, 65535.0) as u16;
            r[12..14].copy_from_slice(&level.to_le_bytes());
            r[14] = byte(2).min(15) | (byte(3).min(15) << 4);
            r[16] = byte(1);
            let source = value(4).clamp(0.0, 65535.0) as u16;
            r[20..22].copy_from_slice(&source.to_le_bytes());
            let t = f64::from(value(5)) + gps_origin;
            r[22..30].copy_from_slice(&t.to_le_bytes());
            if let Some(colors) = &cloud.colors {
                for (c, v) in colors[i][..3].iter().enumerate() {
                    r[30 + 2 * c..32 + 2 * c].copy_from_slice(&(u16::from(*v) * 257).to_le_bytes());
                }
            }
            let mut at = base;
            let mut put = |bytes: &[u8]| {
                r[at..at + bytes.len()].copy_from_slice(bytes);
                at += bytes.len();
            };
            if let Some(normals) = &cloud.normals {
                let e = octahedral(normals[i]);
                put(&unorm16(e.x).to_le_bytes());
                put(&unorm16(e.y).to_le_bytes());
            }
            if let (Some(radii), Some(code)) = (&cloud.radii, radius) {
                match code {
                    RadiusCode::Scaled { scale, offset } => {
                        let q = ((f64::from(radii[i]) - offset) / scale).round();
                        put(&(q.clamp(0.0, 65535.0) as u16).to_le_bytes());
                    }
                    RadiusCode::Float => put(&radii[i].to_le_bytes()),
                }
            }
            for s in &others {
                put(&s.values[i].to_le_bytes());
            }
        });
    Ok((layout, records))
}

/// A LAS file's record format as the re-encoding needs it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Source {
    pub format: u8,
    /// Bytes of one record in the file.
    pub len: usize,
    pub scale: DVec3,
    pub offset: DVec3,
    /// Copy the extra bytes after the standard fields.
    pub keep_extra: bool,
}

impl Source {
    fn base(&self) -> usize {
        match self.format {
            0 => 20,
            1 => 28,
            2 => 26,
            3 => 34,
            4 => 57,
            5 => 63,
            f => base_len(f),
        }
    }

    /// Byte offset of the GPS time in a record, if the format has one.
    fn gps_at(&self) -> Option<usize> {
        match self.format {
            1 | 3 | 4 | 5 => Some(20),
            0 | 2 => None,
            _ => Some(22),
        }
    }

    /// Byte offset of the colour in a record, if the format has one.
    fn rgb_at(&self) -> Option<usize> {
        match self.format {
            2 => Some(20),
            3 | 5 => Some(28),
            7 | 8 | 10 => Some(30),
            _ => None,
        }
    }

    /// Whether `layout`'s records can be this source's records copied as they are.
    pub fn is_identity(&self, layout: &Layout) -> bool {
        self.format == layout.format
            && self.len == layout.record_len()
            && self.scale == layout.scale
            && self.offset == layout.offset
    }

    /// Re-encodes the records `src` (back to back, this source's format) as `layout`'s records
    /// into `dst` (as many records).
    pub fn transcode(&self, layout: &Layout, src: &[u8], dst: &mut [u8]) {
        if self.is_identity(layout) {
            dst.copy_from_slice(src);
            return;
        }
        let out_len = layout.record_len();
        let same_grid = self.scale == layout.scale && self.offset == layout.offset;
        let (base, out_base) = (self.base(), base_len(layout.format));
        let extra = usize::from(layout.extra_bytes);
        for (s, r) in src
            .chunks_exact(self.len)
            .zip(dst.chunks_exact_mut(out_len))
        {
            if same_grid {
                r[..12].copy_from_slice(&s[..12]);
            } else {
                for axis in 0..3 {
                    let q = f64::from(i32::from_le_bytes(
                        s[4 * axis..4 * axis + 4].try_into().expect("4 bytes"),
                    ));
                    let w = q * self.scale[axis] + self.offset[axis];
                    let q = ((w - layout.offset[axis]) / layout.scale[axis]).round() as i32;
                    r[4 * axis..4 * axis + 4].copy_from_slice(&q.to_le_bytes());
                }
            }
            r[12..14].copy_from_slice(&s[12..14]);
            if self.format <= 5 {
                let (b, c) = (s[14], s[15]);
                r[14] = (b & 7) | (((b >> 3) & 7) << 4);
                r[15] = (c >> 5) | (((b >> 6) & 1) << 6) | ((b >> 7) << 7);
                r[16] = c & 31;
                r[17] = s[17];
                let angle = (f32::from(s[16] as i8) / 0.006).round() as i16;
                r[18..20].copy_from_slice(&angle.to_le_bytes());
                r[20..22].copy_from_slice(&s[18..20]);
            } else {
                r[14..22].copy_from_slice(&s[14..22]);
            }
            match self.gps_at() {
                Some(at) => r[22..30].copy_from_slice(&s[at..at + 8]),
                None => r[22..30].fill(0),
            }
            if layout.format == 7 {
                match self.rgb_at() {
                    Some(at) => r[30..36].copy_from_slice(&s[at..at + 6]),
                    None => r[30..36].fill(0),
                }
            }
            if extra > 0 {
                r[out_base..out_base + extra].copy_from_slice(&s[base..base + extra]);
            }
        }
        debug_assert!(self.keep_extra || extra == 0);
    }
}

/// The CRS VLRs of a LAS header (WKT, GeoTIFF keys and their parameters), to carry into the
/// output.
pub fn crs_vlrs<'a>(vlrs: impl Iterator<Item = &'a las::Vlr>) -> Vec<RawVlr> {
    vlrs.filter(|v| {
        v.user_id.trim_end_matches('\0') == "LASF_Projection"
            && matches!(v.record_id, 2111 | 2112 | 34735 | 34736 | 34737)
    })
    .map(|v| RawVlr {
        user_id: v.user_id.clone(),
        record_id: v.record_id,
        description: v.description.clone(),
        data: v.data.clone(),
    })
    .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn legacy_records_become_format_6() {
        let mut s = vec![0u8; 34];
        s[..4].copy_from_slice(&7i32.to_le_bytes());
        s[12..14].copy_from_slice(&300u16.to_le_bytes());
        s[14] = 2 | (3 << 3) | (1 << 6);
        s[15] = 6 | (1 << 5);
        s[16] = (-30i8) as u8;
        s[17] = 9;
        s[18..20].copy_from_slice(&44u16.to_le_bytes());
        s[20..28].copy_from_slice(&5.5f64.to_le_bytes());
        s[28..34].copy_from_slice(&[1, 2, 3, 4, 5, 6]);
        let source = Source {
            format: 3,
            len: 34,
            scale: DVec3::splat(0.01),
            offset: DVec3::ZERO,
            keep_extra: false,
        };
        let layout = Layout {
            format: 7,
            extra_bytes: 0,
            descriptors: Vec::new(),
            scale: DVec3::splat(0.01),
            offset: DVec3::ZERO,
            vlrs: Vec::new(),
            standard_gps_time: false,
        };
        let mut r = vec![0u8; 36];
        source.transcode(&layout, &s, &mut r);
        assert_eq!(&r[..4], &7i32.to_le_bytes());
        assert_eq!(&r[12..14], &300u16.to_le_bytes());
        assert_eq!(r[14], 2 | (3 << 4));
        assert_eq!(r[15], 1 | (1 << 6));
        assert_eq!(r[16], 6);
        assert_eq!(r[17], 9);
        assert_eq!(i16::from_le_bytes([r[18], r[19]]), -5000);
        assert_eq!(&r[20..22], &44u16.to_le_bytes());
        assert_eq!(&r[22..30], &5.5f64.to_le_bytes());
        assert_eq!(&r[30..36], &[1, 2, 3, 4, 5, 6]);
    }
}
