//! Virtual point clouds (`.vpc`): several LAS, LAZ or COPC files read as one scene.
//!
//! A `.vpc` is a STAC ItemCollection (a GeoJSON `FeatureCollection`) with one STAC Item per
//! file, as written by PDAL wrench and QGIS (`vpc-spec.md` in PDAL/wrench). Each item carries
//! its point count (`pc:count`), its bounds in the file's own CRS (`proj:bbox`, read in
//! preference to the WGS 84 `bbox`) and a `data` asset whose `href` is relative to the
//! `.vpc`'s location (a path or an HTTP(S) URL) or absolute.
//!
//! [`parse`] checks what a reader needs and names the `.vpc` and the item in its errors;
//! [`write`] writes a spec-complete collection from per-file [`TileSummary`]s, which
//! [`summarize`] takes from a written file's header.

use std::collections::BTreeMap;
use std::path::{Component, Path, PathBuf};

use anyhow::{bail, Context};
use serde::{Deserialize, Serialize};
use serde_json::{json, Value};

use crate::source::is_url;

/// The STAC version written.
pub const STAC_VERSION: &str = "1.0.0";
/// The point-cloud extension's schema.
pub const POINTCLOUD_EXTENSION: &str =
    "https://stac-extensions.github.io/pointcloud/v1.0.0/schema.json";
/// The projection extension's schema.
pub const PROJECTION_EXTENSION: &str =
    "https://stac-extensions.github.io/projection/v1.1.0/schema.json";
/// The largest `.vpc` read (its items are a few hundred bytes each).
pub const MAX_BYTES: u64 = 256 << 20;

/// A file's point encoding, as `pc:encoding` names it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Encoding {
    Las,
    Laz,
    Copc,
}

impl Encoding {
    /// The `pc:encoding` value (the media types wrench writes).
    pub fn media_type(self) -> &'static str {
        match self {
            Encoding::Las => "application/vnd.las",
            Encoding::Laz => "application/vnd.laszip",
            Encoding::Copc => "application/vnd.laszip+copc",
        }
    }

    /// The encoding of a `pc:encoding` value, or else of the file name's extension; `None`
    /// when neither tells.
    pub fn of(encoding: Option<&str>, href: &str) -> Option<Encoding> {
        let named = encoding.map(|e| e.to_ascii_lowercase());
        match named.as_deref() {
            Some(e) if e.contains("copc") => return Some(Encoding::Copc),
            Some(e) if e.contains("laz") => return Some(Encoding::Laz),
            Some(e) if e.ends_with("las") => return Some(Encoding::Las),
            _ => {}
        }
        let path = href.split(['?', '#']).next().unwrap_or(href);
        let lower = path.to_ascii_lowercase();
        if lower.ends_with(".copc.laz") {
            Some(Encoding::Copc)
        } else if lower.ends_with(".laz") {
            Some(Encoding::Laz)
        } else if lower.ends_with(".las") {
            Some(Encoding::Las)
        } else {
            None
        }
    }
}

/// A coordinate reference system as a `.vpc` records it.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Crs {
    /// The EPSG code (`proj:epsg`).
    pub epsg: Option<u32>,
    /// A WKT 2 definition (`proj:wkt2`).
    pub wkt2: Option<String>,
}

impl Crs {
    /// Whether coordinates are WGS 84 longitude, latitude (EPSG:4326, or 4979 with
    /// ellipsoidal heights): only then are a file's bounds written as the item's `bbox`.
    pub fn is_wgs84(&self) -> bool {
        matches!(self.epsg, Some(4326 | 4979))
    }

    /// The CRS of a LAS file's VLRs: the OGC WKT (`LASF_Projection` record 2112; kept as
    /// `wkt2` when it is WKT 2, its top-level EPSG code taken either way), else the EPSG code
    /// of the GeoTIFF keys (record 34735: projected 3072, else geographic 2048). `None`
    /// without either.
    pub fn of_vlrs<'a>(vlrs: impl Iterator<Item = &'a las::Vlr> + Clone) -> Option<Crs> {
        let projection = |id: u16| {
            vlrs.clone().find(|v| {
                v.user_id.trim_end_matches('\0') == "LASF_Projection" && v.record_id == id
            })
        };
        if let Some(wkt) = projection(2112) {
            let text = String::from_utf8_lossy(&wkt.data);
            let text = text.trim_end_matches('\0').trim();
            let wkt2 = [
                "PROJCRS",
                "GEOGCRS",
                "GEODCRS",
                "COMPOUNDCRS",
                "BOUNDCRS",
                "VERTCRS",
            ]
            .iter()
            .any(|k| text.starts_with(k));
            return Some(Crs {
                epsg: wkt_epsg(text),
                wkt2: wkt2.then(|| text.to_owned()),
            });
        }
        let keys: Vec<u16> = projection(34735)?
            .data
            .chunks_exact(2)
            .map(|b| u16::from_le_bytes([b[0], b[1]]))
            .collect();
        let count = usize::from(*keys.get(3)?);
        let code = |id: u16| {
            keys.get(4..)?
                .chunks_exact(4)
                .take(count)
                .find(|k| k[0] == id && k[1] == 0 && k[3] != 0 && k[3] != 32767)
                .map(|k| u32::from(k[3]))
        };
        Some(Crs {
            epsg: code(3072).or_else(|| code(2048)),
            wkt2: None,
        })
    }
}

/// The top-level authority code of a WKT when the authority is EPSG
/// (`AUTHORITY["EPSG","32633"]` in WKT 1, `ID["EPSG",32633]` in WKT 2).
fn wkt_epsg(wkt: &str) -> Option<u32> {
    let mut depth = 0usize;
    let mut quoted = false;
    let mut code = None;
    for (i, c) in wkt.char_indices() {
        match c {
            '"' => quoted = !quoted,
            '[' | '(' if !quoted => {
                depth += 1;
                let keyword = wkt[..i]
                    .rsplit(|c: char| c == ',' || c == '[' || c == '(' || c.is_whitespace())
                    .next()
                    .unwrap_or_default();
                if depth == 2 && matches!(keyword, "AUTHORITY" | "ID") {
                    let args = &wkt[i + 1..];
                    let args = &args[..args.find([']', ')']).unwrap_or(args.len())];
                    let mut parts = args.split(',').map(|p| p.trim().trim_matches('"'));
                    if let (Some(authority), Some(number)) = (parts.next(), parts.next()) {
                        if authority.eq_ignore_ascii_case("EPSG") {
                            code = number.parse().ok();
                        }
                    }
                }
            }
            ']' | ')' if !quoted => depth = depth.saturating_sub(1),
            _ => {}
        }
    }
    code
}

// ----- The data model (the fields a reader uses; others are kept as they are) -----

/// A STAC ItemCollection.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Collection {
    #[serde(rename = "type")]
    pub kind: String,
    pub features: Vec<Item>,
}

/// A STAC Item: one file.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Item {
    #[serde(rename = "type")]
    pub kind: String,
    #[serde(default)]
    pub stac_version: Option<String>,
    #[serde(default)]
    pub stac_extensions: Vec<String>,
    pub id: String,
    #[serde(default)]
    pub geometry: Option<Value>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bbox: Option<Vec<f64>>,
    pub properties: Properties,
    pub assets: BTreeMap<String, Asset>,
    #[serde(default)]
    pub links: Vec<Value>,
}

/// An item's properties.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Properties {
    #[serde(default)]
    pub datetime: Option<String>,
    #[serde(rename = "pc:count")]
    pub count: u64,
    #[serde(rename = "pc:type", default, skip_serializing_if = "Option::is_none")]
    pub pc_type: Option<String>,
    #[serde(
        rename = "pc:encoding",
        default,
        skip_serializing_if = "Option::is_none"
    )]
    pub encoding: Option<String>,
    #[serde(
        rename = "pc:schemas",
        default,
        skip_serializing_if = "Option::is_none"
    )]
    pub schemas: Option<Vec<Value>>,
    #[serde(rename = "proj:bbox", default, skip_serializing_if = "Option::is_none")]
    pub proj_bbox: Option<Vec<f64>>,
    #[serde(
        rename = "proj:geometry",
        default,
        skip_serializing_if = "Option::is_none"
    )]
    pub proj_geometry: Option<Value>,
    #[serde(rename = "proj:epsg", default)]
    pub epsg: Option<u32>,
    #[serde(rename = "proj:wkt2", default, skip_serializing_if = "Option::is_none")]
    pub wkt2: Option<String>,
    #[serde(
        rename = "proj:projjson",
        default,
        skip_serializing_if = "Option::is_none"
    )]
    pub projjson: Option<Value>,
}

/// An item's asset.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Asset {
    pub href: String,
    #[serde(default)]
    pub roles: Vec<String>,
    #[serde(rename = "type", default, skip_serializing_if = "Option::is_none")]
    pub media_type: Option<String>,
}

// ----- Reading -----

/// One file of a parsed `.vpc`, ready to open.
#[derive(Clone, Debug, PartialEq)]
pub struct Tile {
    /// The item's `id`.
    pub id: String,
    /// The `data` asset's `href` as written.
    pub href: String,
    /// Where to read it: `href` resolved against the `.vpc`'s location.
    pub location: String,
    /// Points (`pc:count`).
    pub points: u64,
    /// The bounds in the file's CRS: from a 3D `proj:bbox`, else from the WGS 84 `bbox` when the
    /// CRS is WGS 84. `None` when the item has neither (the file's header gives them).
    pub bounds: Option<([f64; 3], [f64; 3])>,
    pub encoding: Encoding,
    pub crs: Option<Crs>,
}

/// A parsed `.vpc`.
#[derive(Clone, Debug, PartialEq)]
pub struct Vpc {
    /// Its path or URL.
    pub location: String,
    pub tiles: Vec<Tile>,
}

impl Vpc {
    /// Points over all tiles.
    pub fn points(&self) -> u64 {
        self.tiles.iter().map(|t| t.points).sum()
    }

    /// The union of the tiles' known bounds.
    pub fn bounds(&self) -> Option<([f64; 3], [f64; 3])> {
        self.tiles
            .iter()
            .filter_map(|t| t.bounds)
            .reduce(|(a, b), (c, d)| {
                (
                    std::array::from_fn(|i| a[i].min(c[i])),
                    std::array::from_fn(|i| b[i].max(d[i])),
                )
            })
    }
}

/// Whether `location` names a virtual point cloud (by its extension).
pub fn is_vpc(location: &str) -> bool {
    let path = location.split(['?', '#']).next().unwrap_or(location);
    path.to_ascii_lowercase().ends_with(".vpc")
}

/// Parses the text of the `.vpc` at `location` (used in messages and to resolve hrefs).
pub fn parse(location: &str, text: &[u8]) -> anyhow::Result<Vpc> {
    if text.len() as u64 > MAX_BYTES {
        bail!(
            "{location}: {} bytes; a virtual point cloud of at most {MAX_BYTES} bytes expected",
            text.len()
        );
    }
    let value: Value = serde_json::from_slice(text).map_err(|e| {
        anyhow::anyhow!(
            "{location}: line {}, column {}: invalid JSON: {}",
            e.line(),
            e.column(),
            strip_position(&e.to_string())
        )
    })?;
    let kind = value.get("type").and_then(Value::as_str);
    if kind != Some("FeatureCollection") {
        bail!(
            "{location}: a STAC ItemCollection (\"type\": \"FeatureCollection\") expected, found {}",
            match value.get("type") {
                Some(t) => format!("\"type\": {t}"),
                None => "no \"type\"".to_owned(),
            }
        );
    }
    let Some(features) = value.get("features").and_then(Value::as_array) else {
        bail!("{location}: a \"features\" array of STAC Items expected");
    };
    if features.is_empty() {
        bail!("{location}: no features; at least one STAC Item expected");
    }
    let tiles = features
        .iter()
        .enumerate()
        .map(|(i, f)| tile(location, i, f))
        .collect::<anyhow::Result<Vec<_>>>()?;
    Ok(Vpc {
        location: location.to_owned(),
        tiles,
    })
}

/// serde_json's message without its trailing " at line L column C".
fn strip_position(message: &str) -> &str {
    message
        .rfind(" at line ")
        .map_or(message, |at| &message[..at])
}

fn tile(location: &str, index: usize, feature: &Value) -> anyhow::Result<Tile> {
    let id = feature
        .get("id")
        .and_then(Value::as_str)
        .map_or(String::new(), |id| format!(" (id \"{id}\")"));
    let at = format!("{location}: feature {index}{id}");
    let item: Item = serde_json::from_value(feature.clone())
        .map_err(|e| anyhow::anyhow!("{at}: {}", strip_position(&e.to_string())))?;
    if item.kind != "Feature" {
        bail!(
            "{at}: a STAC Item (\"type\": \"Feature\") expected, found \"type\": \"{}\"",
            item.kind
        );
    }
    let asset = item
        .assets
        .get("data")
        .or_else(|| {
            item.assets
                .values()
                .find(|a| a.roles.iter().any(|r| r == "data"))
        })
        .with_context(|| {
            format!("{at}: no data asset (an asset named \"data\" or with the role \"data\")")
        })?;
    if asset.href.is_empty() {
        bail!("{at}: the data asset's href is empty");
    }
    let p = &item.properties;
    let encoding = Encoding::of(
        p.encoding
            .as_deref()
            .or(asset.media_type.as_deref()),
        &asset.href,
    )
    .with_context(|| {
        format!(
            "{at}: cannot tell the encoding of \"{}\": pc:encoding or a .las, .laz or .copc.laz href expected",
            asset.href
        )
    })?;
    let crs = (p.epsg.is_some() || p.wkt2.is_some()).then(|| Crs {
        epsg: p.epsg,
        wkt2: p.wkt2.clone(),
    });
    let check = |name: &str, b: &[f64]| -> anyhow::Result<()> {
        if let Some(v) = b.iter().find(|v| !v.is_finite()) {
            bail!("{at}: {name} holds {v}; finite numbers expected");
        }
        Ok(())
    };
    let bounds = match (&p.proj_bbox, &item.bbox) {
        (Some(b), _) if b.len() == 6 => {
            check("proj:bbox", b)?;
            Some(([b[0], b[1], b[2]], [b[3], b[4], b[5]]))
        }
        (Some(b), _) if b.len() == 4 => {
            check("proj:bbox", b)?;
            None
        }
        (Some(b), _) => bail!(
            "{at}: proj:bbox has {} numbers; 4 (2D) or 6 (3D) expected",
            b.len()
        ),
        (None, Some(b)) if b.len() == 6 && crs.as_ref().is_some_and(Crs::is_wgs84) => {
            check("bbox", b)?;
            Some(([b[0], b[1], b[2]], [b[3], b[4], b[5]]))
        }
        _ => None,
    };
    if let Some((lo, hi)) = bounds {
        if (0..3).any(|i| lo[i] > hi[i]) {
            bail!("{at}: proj:bbox minimum {lo:?} exceeds its maximum {hi:?}");
        }
    }
    Ok(Tile {
        id: item.id.clone(),
        href: asset.href.clone(),
        location: resolve(location, &asset.href),
        points: p.count,
        bounds,
        encoding,
        crs,
    })
}

/// Reads and parses the `.vpc` at `location` (a path or an HTTP(S) URL).
pub fn read(location: &str, http: &crate::source::HttpOptions) -> anyhow::Result<Vpc> {
    let text = if is_url(location) {
        let source = crate::source::open(location, http).map_err(|e| anyhow::anyhow!(e))?;
        if source.len() > MAX_BYTES {
            bail!(
                "{location}: {} bytes; a virtual point cloud of at most {MAX_BYTES} bytes expected",
                source.len()
            );
        }
        source
            .read_at(0, source.len())
            .map_err(|e| anyhow::anyhow!(e))?
    } else {
        let path = Path::new(location);
        let size = std::fs::metadata(path)
            .with_context(|| format!("{location}: cannot read file"))?
            .len();
        if size > MAX_BYTES {
            bail!("{location}: {size} bytes; a virtual point cloud of at most {MAX_BYTES} bytes expected");
        }
        std::fs::read(path).with_context(|| format!("{location}: cannot read file"))?
    };
    parse(location, &text)
}

/// `href` resolved against the `.vpc` at `base`: an absolute URL or path as it is, else
/// relative to the directory holding `base` (`./` and `../` folded; a URL's `/path` taken from
/// its host).
pub fn resolve(base: &str, href: &str) -> String {
    if is_url(href) {
        return href.to_owned();
    }
    let href = href.strip_prefix("file://").unwrap_or(href);
    if is_url(base) {
        let scheme_end = base.find("://").map_or(0, |i| i + 3);
        let path_at = base[scheme_end..]
            .find('/')
            .map_or(base.len(), |i| scheme_end + i);
        let (root, path) = base.split_at(path_at);
        let path = path.split(['?', '#']).next().unwrap_or(path);
        let dir = if href.starts_with('/') {
            ""
        } else {
            path.rsplit_once('/').map_or("", |(d, _)| d)
        };
        let mut parts: Vec<&str> = dir.split('/').filter(|s| !s.is_empty()).collect();
        for part in href.split('/') {
            match part {
                "" | "." => {}
                ".." => {
                    parts.pop();
                }
                p => parts.push(p),
            }
        }
        let trailing = if href.ends_with('/') { "/" } else { "" };
        return format!("{root}/{}{trailing}", parts.join("/"));
    }
    let path = Path::new(href);
    if path.is_absolute() {
        return href.to_owned();
    }
    let dir = Path::new(base).parent().unwrap_or(Path::new(""));
    let mut out = PathBuf::new();
    for c in dir.join(path).components() {
        match c {
            Component::CurDir => {}
            Component::ParentDir
                if matches!(out.components().next_back(), Some(Component::Normal(_))) =>
            {
                out.pop();
            }
            c => out.push(c),
        }
    }
    out.display().to_string()
}

// ----- Writing -----

/// What the writer needs of one file.
#[derive(Clone, Debug, PartialEq)]
pub struct TileSummary {
    /// The file, relative to the `.vpc` (or absolute).
    pub href: String,
    /// Bounds in the file's CRS.
    pub min: [f64; 3],
    pub max: [f64; 3],
    pub points: u64,
    pub crs: Option<Crs>,
    pub encoding: Encoding,
    /// The LAS point data record format (0 to 10), for `pc:schemas`.
    pub point_format: u8,
    /// The header's creation date, `YYYY-MM-DD`.
    pub date: Option<String>,
}

/// The summary of the LAS, LAZ or COPC file at `file`, its href written relative to the
/// directory of the `.vpc` at `vpc`.
pub fn summarize(vpc: &Path, file: &Path) -> anyhow::Result<TileSummary> {
    let name = file.display().to_string();
    let reader = las::Reader::from_path(file)
        .map_err(|e| anyhow::anyhow!("{name}: cannot read the LAS header: {e}"))?;
    let header = reader.header();
    let b = header.bounds();
    let format = header.point_format();
    let copc = header
        .vlrs()
        .iter()
        .any(|v| v.user_id.trim_end_matches('\0') == "copc" && v.record_id == 1);
    let encoding = match (copc, format.is_compressed) {
        (true, _) => Encoding::Copc,
        (false, true) => Encoding::Laz,
        (false, false) => Encoding::Las,
    };
    Ok(TileSummary {
        href: relative(vpc, file),
        min: [b.min.x, b.min.y, b.min.z],
        max: [b.max.x, b.max.y, b.max.z],
        points: header.number_of_points(),
        crs: Crs::of_vlrs(header.vlrs().iter().chain(header.evlrs())),
        encoding,
        point_format: format.to_u8().unwrap_or_default(),
        date: header.date().map(|d| d.to_string()),
    })
}

/// `file` as a path relative to the directory holding `vpc` (`/` separated), or absolute when
/// they share no root.
pub fn relative(vpc: &Path, file: &Path) -> String {
    let absolute = |p: &Path| -> PathBuf {
        let p = if p.is_absolute() {
            p.to_path_buf()
        } else {
            std::env::current_dir().unwrap_or_default().join(p)
        };
        let mut out = PathBuf::new();
        for c in p.components() {
            match c {
                Component::CurDir => {}
                Component::ParentDir => {
                    out.pop();
                }
                c => out.push(c),
            }
        }
        out
    };
    let dir = absolute(vpc.parent().unwrap_or(Path::new("")));
    let file = absolute(file);
    let a: Vec<_> = dir.components().collect();
    let b: Vec<_> = file.components().collect();
    let common = a.iter().zip(&b).take_while(|(x, y)| x == y).count();
    if common == 0 {
        return file.display().to_string();
    }
    let mut parts: Vec<String> = vec!["..".to_owned(); a.len() - common];
    parts.extend(
        b[common..]
            .iter()
            .map(|c| c.as_os_str().to_string_lossy().into_owned()),
    );
    let joined = parts.join("/");
    if joined.starts_with("..") {
        joined
    } else {
        format!("./{joined}")
    }
}

/// The `pc:schemas` of LAS point format `format`: the standard dimensions (extra bytes are
/// not listed).
fn schemas(format: u8) -> Vec<Value> {
    let dim = |name: &str, size: u32, kind: &str| json!({"name": name, "size": size, "type": kind});
    let mut out = vec![
        dim("X", 4, "signed"),
        dim("Y", 4, "signed"),
        dim("Z", 4, "signed"),
        dim("Intensity", 2, "unsigned"),
        dim("ReturnNumber", 1, "unsigned"),
        dim("NumberOfReturns", 1, "unsigned"),
    ];
    if format >= 6 {
        out.push(dim("ClassFlags", 1, "unsigned"));
    }
    out.extend([
        dim("ScanDirectionFlag", 1, "unsigned"),
        dim("EdgeOfFlightLine", 1, "unsigned"),
        dim("Classification", 1, "unsigned"),
    ]);
    if format >= 6 {
        out.push(dim("ScanChannel", 1, "unsigned"));
        out.push(dim("ScanAngleRank", 4, "floating"));
    } else {
        out.push(dim("ScanAngleRank", 1, "signed"));
    }
    out.extend([
        dim("UserData", 1, "unsigned"),
        dim("PointSourceId", 2, "unsigned"),
    ]);
    if format != 0 && format != 2 {
        out.push(dim("GpsTime", 8, "floating"));
    }
    if matches!(format, 2 | 3 | 5 | 7 | 8 | 10) {
        out.extend([
            dim("Red", 2, "unsigned"),
            dim("Green", 2, "unsigned"),
            dim("Blue", 2, "unsigned"),
        ]);
    }
    if matches!(format, 8 | 10) {
        out.push(dim("Infrared", 2, "unsigned"));
    }
    out
}

/// The STAC Item of `tile` (see [`write`]).
pub fn item(tile: &TileSummary) -> anyhow::Result<Value> {
    let (lo, hi) = (tile.min, tile.max);
    if lo.iter().chain(&hi).any(|v| !v.is_finite()) {
        bail!(
            "{}: bounds {lo:?} .. {hi:?} are not finite; a .vpc item needs finite bounds",
            tile.href
        );
    }
    let ring = json!([[
        [lo[0], lo[1]],
        [hi[0], lo[1]],
        [hi[0], hi[1]],
        [lo[0], hi[1]],
        [lo[0], lo[1]]
    ]]);
    let polygon = json!({"type": "Polygon", "coordinates": ring});
    let wgs84 = tile.crs.as_ref().is_some_and(Crs::is_wgs84);
    let id = tile
        .href
        .rsplit('/')
        .next()
        .unwrap_or(&tile.href)
        .split('.')
        .next()
        .unwrap_or_default()
        .to_owned();
    let datetime = tile
        .date
        .as_ref()
        .map_or("1970-01-01T00:00:00Z".to_owned(), |d| {
            format!("{d}T00:00:00Z")
        });
    let mut properties = json!({
        "datetime": datetime,
        "pc:count": tile.points,
        "pc:type": "lidar",
        "pc:encoding": tile.encoding.media_type(),
        "pc:schemas": schemas(tile.point_format),
        "proj:bbox": [lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]],
        "proj:geometry": polygon,
        "proj:epsg": tile.crs.as_ref().and_then(|c| c.epsg),
    });
    if let Some(wkt) = tile.crs.as_ref().and_then(|c| c.wkt2.as_ref()) {
        properties["proj:wkt2"] = json!(wkt);
    }
    let mut item = json!({
        "type": "Feature",
        "stac_version": STAC_VERSION,
        "stac_extensions": [POINTCLOUD_EXTENSION, PROJECTION_EXTENSION],
        "id": id,
        "geometry": if wgs84 { polygon.clone() } else { Value::Null },
        "properties": properties,
        "links": [],
        "assets": {
            "data": {
                "href": tile.href,
                "roles": ["data"],
                "type": tile.encoding.media_type(),
            }
        },
    });
    if wgs84 {
        item["bbox"] = json!([lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]]);
    }
    Ok(item)
}

/// Writes the `.vpc` of `tiles` to `path`: one STAC Item per tile with `pc:count`, `pc:type`
/// (`lidar`), `pc:encoding`, `pc:schemas`, a 3D `proj:bbox`, `proj:geometry`, `proj:epsg` (null
/// when unknown) and `proj:wkt2` when the tile's CRS has a WKT 2. The WGS 84 `geometry` and
/// `bbox` are written when the tile's CRS is WGS 84 (its bounds are then longitude, latitude);
/// otherwise `geometry` is null and there is no `bbox`, as STAC allows, since no reprojection
/// is done.
pub fn write(path: &Path, tiles: &[TileSummary]) -> anyhow::Result<()> {
    let features = tiles.iter().map(item).collect::<anyhow::Result<Vec<_>>>()?;
    let collection = json!({"type": "FeatureCollection", "features": features});
    let mut text = serde_json::to_string_pretty(&collection)?;
    text.push('\n');
    std::fs::write(path, text).with_context(|| format!("{}: cannot write", path.display()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn resolves_hrefs_against_paths_and_urls() {
        assert_eq!(
            resolve("data/set.vpc", "./a/t.copc.laz"),
            "data/a/t.copc.laz"
        );
        assert_eq!(resolve("data/set.vpc", "../t.laz"), "t.laz");
        assert_eq!(resolve("set.vpc", "t.laz"), "t.laz");
        assert_eq!(resolve("/d/set.vpc", "/abs/t.laz"), "/abs/t.laz");
        assert_eq!(resolve("/d/set.vpc", "file:///abs/t.laz"), "/abs/t.laz");
        assert_eq!(
            resolve("http://h:8/a/b/set.vpc?x=1", "./t/1.copc.laz"),
            "http://h:8/a/b/t/1.copc.laz"
        );
        assert_eq!(
            resolve("https://h/a/b/set.vpc", "../c.laz"),
            "https://h/a/c.laz"
        );
        assert_eq!(
            resolve("https://h/a/set.vpc", "/r/c.laz"),
            "https://h/r/c.laz"
        );
        assert_eq!(
            resolve("https://h/a/set.vpc", "http://o/c.laz"),
            "http://o/c.laz"
        );
        assert_eq!(resolve("http://h/set.vpc", "c.laz"), "http://h/c.laz");
    }

    #[test]
    fn relative_hrefs() {
        assert_eq!(
            relative(Path::new("/d/x/set.vpc"), Path::new("/d/x/t/1.copc.laz")),
            "./t/1.copc.laz"
        );
        assert_eq!(
            relative(Path::new("/d/x/set.vpc"), Path::new("/d/y/1.laz")),
            "../y/1.laz"
        );
    }

    #[test]
    fn crs_from_wkt_and_geotiff_keys() {
        let vlr = |id: u16, data: Vec<u8>| las::Vlr {
            user_id: "LASF_Projection".into(),
            record_id: id,
            description: String::new(),
            data,
        };
        let wkt2 = r#"PROJCRS["WGS 84 / UTM zone 33N",BASEGEOGCRS["WGS 84",ID["EPSG",4326]],ID["EPSG",32633]]"#;
        let wkt1 = r#"PROJCS["NAD83 / Conus Albers",GEOGCS["NAD83",AUTHORITY["EPSG","4269"]],AUTHORITY["EPSG","5070"]]"#;
        let v = [vlr(2112, wkt2.as_bytes().to_vec())];
        assert_eq!(
            Crs::of_vlrs(v.iter()),
            Some(Crs {
                epsg: Some(32633),
                wkt2: Some(wkt2.to_owned())
            })
        );
        let v = [vlr(2112, wkt1.as_bytes().to_vec())];
        assert_eq!(
            Crs::of_vlrs(v.iter()),
            Some(Crs {
                epsg: Some(5070),
                wkt2: None
            })
        );
        let keys: Vec<u8> = [1u16, 1, 0, 2, 1024, 0, 1, 2, 2048, 0, 1, 4326]
            .iter()
            .flat_map(|k| k.to_le_bytes())
            .collect();
        let v = [vlr(34735, keys)];
        let crs = Crs::of_vlrs(v.iter()).unwrap();
        assert_eq!(crs.epsg, Some(4326));
        assert!(crs.is_wgs84());
        assert_eq!(Crs::of_vlrs([].iter()), None);
    }

    fn summary(crs: Option<Crs>) -> TileSummary {
        TileSummary {
            href: "./t/a.copc.laz".into(),
            min: [1.0, 2.0, 3.0],
            max: [4.0, 5.0, 6.0],
            points: 10,
            crs,
            encoding: Encoding::Copc,
            point_format: 7,
            date: Some("2024-03-01".into()),
        }
    }

    #[test]
    fn written_items_parse_back() {
        let dir = std::env::temp_dir().join(format!("surfel-vpc-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("set.vpc");
        let wgs = Crs {
            epsg: Some(4326),
            wkt2: None,
        };
        write(&path, &[summary(None), summary(Some(wgs.clone()))]).unwrap();
        let text = std::fs::read(&path).unwrap();
        let vpc = parse(&path.display().to_string(), &text).unwrap();
        assert_eq!(vpc.tiles.len(), 2);
        let t = &vpc.tiles[0];
        assert_eq!(t.id, "a");
        assert_eq!(t.location, dir.join("t/a.copc.laz").display().to_string());
        assert_eq!(t.bounds, Some(([1.0, 2.0, 3.0], [4.0, 5.0, 6.0])));
        assert_eq!(t.encoding, Encoding::Copc);
        assert_eq!(t.points, 10);
        assert_eq!(vpc.tiles[1].crs, Some(wgs));
        let v: Value = serde_json::from_slice(&text).unwrap();
        assert!(v["features"][0]["geometry"].is_null());
        assert!(v["features"][0].get("bbox").is_none());
        assert_eq!(
            v["features"][1]["bbox"],
            json!([1.0, 2.0, 3.0, 4.0, 5.0, 6.0])
        );
        assert_eq!(v["features"][1]["geometry"]["type"], "Polygon");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn parse_errors_name_the_file_and_what_was_expected() {
        let err = |text: &str| parse("x.vpc", text.as_bytes()).unwrap_err().to_string();
        assert_eq!(
            err("{\n  \"type\": \"FeatureCollection\",\n  \"features\": [}"),
            "x.vpc: line 3, column 16: invalid JSON: expected value"
        );
        assert_eq!(
            err(r#"{"type": "Feature"}"#),
            "x.vpc: a STAC ItemCollection (\"type\": \"FeatureCollection\") expected, found \"type\": \"Feature\""
        );
        assert_eq!(
            err(r#"{"type": "FeatureCollection", "features": []}"#),
            "x.vpc: no features; at least one STAC Item expected"
        );
        let feature = |props: &str, assets: &str| {
            format!(
                r#"{{"type": "FeatureCollection", "features": [{{"type": "Feature", "id": "t1", "properties": {{{props}}}, "assets": {{{assets}}}}}]}}"#
            )
        };
        let data = r#""data": {"href": "t1.laz", "roles": ["data"]}"#;
        assert_eq!(
            err(&feature("", data)),
            "x.vpc: feature 0 (id \"t1\"): missing field `pc:count`"
        );
        assert_eq!(
            err(&feature(r#""pc:count": 5"#, r#""o": {"href": "t1.laz", "roles": ["overview"]}"#)),
            "x.vpc: feature 0 (id \"t1\"): no data asset (an asset named \"data\" or with the role \"data\")"
        );
        assert_eq!(
            err(&feature(
                r#""pc:count": 5, "proj:bbox": [0, 0, 0, 1, 1e999, 1]"#,
                data
            )),
            "x.vpc: line 1, column 136: invalid JSON: number out of range"
        );
        assert_eq!(
            err(&feature(
                r#""pc:count": 5, "proj:bbox": [0, 0, 0, 1, 1]"#,
                data
            )),
            "x.vpc: feature 0 (id \"t1\"): proj:bbox has 5 numbers; 4 (2D) or 6 (3D) expected"
        );
        assert_eq!(
            err(&feature(r#""pc:count": 5, "proj:bbox": [0, 0, 2, 1, 1, 1]"#, data)),
            "x.vpc: feature 0 (id \"t1\"): proj:bbox minimum [0.0, 0.0, 2.0] exceeds its maximum [1.0, 1.0, 1.0]"
        );
        assert_eq!(
            err(&feature(r#""pc:count": 5"#, r#""data": {"href": "t1.bin"}"#)),
            "x.vpc: feature 0 (id \"t1\"): cannot tell the encoding of \"t1.bin\": pc:encoding or a .las, .laz or .copc.laz href expected"
        );
    }
}
