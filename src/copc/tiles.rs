//! Many inputs to COPC: the files that folders and glob patterns name, one distinct name per
//! input, the CRS a LAS header records, and the conversion of each input into its own COPC file
//! in parallel jobs (`surfel convert --tiles`).

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::mpsc;
use std::time::Instant;

use anyhow::{anyhow, bail, Context as _, Result};

use super::convert::{self, ConvertOptions, ConvertStats};
use super::vpc::{self, Crs, TileSummary};
use crate::scene::format_extension;

/// The format extensions a folder or a pattern contributes (every format the loaders read, in
/// the order [`crate::scene::error::FORMATS`] lists them).
pub const FORMATS: [&str; 11] = [
    "ply", "obj", "pcd", "las", "laz", "copc.laz", "e57", "xyz", "txt", "pts", "csv",
];

/// The COPC files' name ending.
pub const COPC_SUFFIX: &str = ".copc.laz";

/// Whether `path`'s format extension is one of `formats`.
fn is_one_of(path: &Path, formats: &[&str]) -> bool {
    formats.contains(&format_extension(path).as_str())
}

/// `formats` as name endings for a message: `.las, .laz`.
fn endings(formats: &[&str]) -> String {
    let dotted: Vec<String> = formats.iter().map(|f| format!(".{f}")).collect();
    dotted.join(", ")
}

/// Whether `text` is a glob pattern rather than a path (it holds `*`, `?` or `[`).
fn is_pattern(text: &str) -> bool {
    text.contains(['*', '?', '['])
}

/// The input files that `args` name, in order: a file as it is; a folder's files in one of
/// `formats` (format extensions such as [`FORMATS`]; sorted by name, its subfolders' too when
/// `recursive`); a glob pattern that is not an existing path (`tiles/*.laz`, for a shell that
/// passes it on quoted), its matching files in one of `formats`, sorted. Fails on an argument
/// that names nothing, a folder or pattern without such files, and a file named twice.
pub fn expand(args: &[PathBuf], formats: &[&str], recursive: bool) -> Result<Vec<PathBuf>> {
    let mut files = Vec::new();
    for arg in args {
        let text = arg.to_string_lossy();
        if arg.is_dir() {
            let before = files.len();
            folder(arg, formats, recursive, &mut files)?;
            if files.len() == before {
                bail!(
                    "{}: the folder holds no point-cloud file ({}){}",
                    arg.display(),
                    endings(formats),
                    if recursive {
                        ""
                    } else {
                        "; --recursive searches its subfolders too"
                    }
                );
            }
        } else if arg.exists() {
            files.push(arg.clone());
        } else if !is_pattern(&text) {
            bail!("{}: no such file or folder", arg.display());
        } else {
            let paths =
                glob::glob(&text).map_err(|e| anyhow!("{text}: not a valid pattern: {e}"))?;
            let mut matched = Vec::new();
            for path in paths {
                let path = path.map_err(|e| anyhow!("{text}: {e}"))?;
                if path.is_file() && is_one_of(&path, formats) {
                    matched.push(path);
                }
            }
            if matched.is_empty() {
                bail!(
                    "{text}: the pattern matches no point-cloud file ({})",
                    endings(formats)
                );
            }
            matched.sort();
            files.extend(matched);
        }
    }
    let mut seen: HashMap<PathBuf, &Path> = HashMap::new();
    for file in &files {
        let key = std::fs::canonicalize(file).unwrap_or_else(|_| file.clone());
        if let Some(first) = seen.insert(key, file) {
            bail!(
                "{}: given twice (first as {}); each input is converted once",
                file.display(),
                first.display()
            );
        }
    }
    Ok(files)
}

/// Appends `dir`'s files in one of `formats`, sorted by name (then its subfolders' when
/// `recursive`; a link to a folder is not followed, so a link back up ends nothing).
fn folder(dir: &Path, formats: &[&str], recursive: bool, files: &mut Vec<PathBuf>) -> Result<()> {
    let mut entries: Vec<PathBuf> = std::fs::read_dir(dir)
        .with_context(|| format!("{}: cannot list the folder", dir.display()))?
        .map(|e| e.map(|e| e.path()))
        .collect::<std::io::Result<_>>()
        .with_context(|| format!("{}: cannot list the folder", dir.display()))?;
    entries.sort();
    let mut subfolders = Vec::new();
    for path in entries {
        if std::fs::symlink_metadata(&path).is_ok_and(|m| m.is_dir()) {
            subfolders.push(path);
        } else if path.is_file() && is_one_of(&path, formats) {
            files.push(path);
        }
    }
    if recursive {
        for sub in subfolders {
            folder(&sub, formats, true, files)?;
        }
    }
    Ok(())
}

/// `path`'s file name without its format extension (`a/x.copc.laz` and `a/x.las`: `x`).
fn stem(path: &Path) -> String {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let extension = format_extension(path);
    if extension.is_empty() {
        return name;
    }
    name[..name.len() - extension.len() - 1].to_owned()
}

/// One name per input, distinct ignoring case (an object store or a case-insensitive file
/// system would merge two that differ in case only): the file's stem; inputs sharing a stem are
/// named `FOLDER-STEM` after the folder holding each; names still shared get `-2`, `-3`, … on
/// all but the first in input order.
pub fn tile_names(inputs: &[PathBuf]) -> Vec<String> {
    let key = |name: &str| name.to_lowercase();
    let stems: Vec<String> = inputs.iter().map(|p| stem(p)).collect();
    let mut count: HashMap<String, usize> = HashMap::new();
    for s in &stems {
        *count.entry(key(s)).or_default() += 1;
    }
    let named: Vec<String> = inputs
        .iter()
        .zip(&stems)
        .map(|(path, s)| {
            if count[&key(s)] == 1 {
                return s.clone();
            }
            match path
                .parent()
                .and_then(Path::file_name)
                .map(|p| p.to_string_lossy())
            {
                Some(parent) => format!("{parent}-{s}"),
                None => s.clone(),
            }
        })
        .collect();
    let mut taken: std::collections::HashSet<String> = std::collections::HashSet::new();
    named
        .into_iter()
        .map(|name| {
            let mut candidate = name.clone();
            let mut k = 2;
            while !taken.insert(key(&candidate)) {
                candidate = format!("{name}-{k}");
                k += 1;
            }
            candidate
        })
        .collect()
}

/// The header of the LAS, LAZ or COPC file `path`; `None` for another format or a header that
/// cannot be read (the conversion reports that, with the loader's message).
pub fn las_header(path: &Path) -> Option<las::Header> {
    if !matches!(format_extension(path).as_str(), "las" | "laz" | "copc.laz") {
        return None;
    }
    let reader = crate::scene::guard::third_party(|| las::Reader::from_path(path))
        .ok()?
        .ok()?;
    Some(reader.header().clone())
}

/// Whether `vlr` is a WKT record (`LASF_Projection` 2112) holding no text, which a COPC writer
/// puts in a file without a CRS.
fn empty_wkt(vlr: &las::Vlr) -> bool {
    vlr.user_id.trim_end_matches('\0') == "LASF_Projection"
        && vlr.record_id == 2112
        && String::from_utf8_lossy(&vlr.data)
            .trim_end_matches('\0')
            .trim()
            .is_empty()
}

/// The CRS `header` records as `surfel info` names it (the WKT's name and authority code, or
/// the GeoTIFF keys' EPSG codes); `None` without one (an empty WKT record is none).
pub fn crs_name(header: &las::Header) -> Option<String> {
    let vlrs: Vec<&las::Vlr> = header
        .vlrs()
        .iter()
        .chain(header.evlrs())
        .filter(|v| !empty_wkt(v))
        .collect();
    crate::scene::las::crs(vlrs.into_iter())
}

/// [`crs_name`] of `path`'s LAS header, when it has one.
pub fn input_crs(path: &Path) -> Option<String> {
    crs_name(&las_header(path)?)
}

/// Fails when two of `inputs` record different CRSs (a merged file has one): names both files
/// and their CRSs. Returns the warning for inputs some of which record none.
pub fn check_one_crs(inputs: &[PathBuf]) -> Result<Option<String>> {
    let crs: Vec<Option<String>> = inputs.iter().map(|p| input_crs(p)).collect();
    let mut first: Option<(&PathBuf, &String)> = None;
    for (path, c) in inputs.iter().zip(&crs) {
        let Some(c) = c else { continue };
        match first {
            None => first = Some((path, c)),
            Some((p0, c0)) if c0 != c => bail!(
                "{} has the CRS {}, {} has {}: a merged COPC file has one CRS (reproject them \
                 to one, or convert them apart with --tiles)",
                p0.display(),
                c0,
                path.display(),
                c
            ),
            Some(_) => {}
        }
    }
    let without = crs.iter().filter(|c| c.is_none()).count();
    Ok(match first {
        Some((p0, c0)) if without > 0 => Some(format!(
            "{without} of {} inputs record no CRS; the output is taken to be in {}'s, {}",
            inputs.len(),
            p0.display(),
            c0
        )),
        _ => None,
    })
}

/// The warning for tiles in more than one CRS (a virtual point cloud's tiles should share one),
/// naming each CRS and its first tile.
pub fn mixed_crs_warning(inputs: &[PathBuf], crs: &[Option<String>]) -> Option<String> {
    let mut distinct: Vec<(&str, &Path)> = Vec::new();
    for (path, c) in inputs.iter().zip(crs) {
        let name = c.as_deref().unwrap_or("none");
        if !distinct.iter().any(|(n, _)| *n == name) {
            distinct.push((name, path));
        }
    }
    (distinct.len() > 1).then(|| {
        let list: Vec<String> = distinct
            .iter()
            .map(|(name, path)| format!("{name} ({})", path.display()))
            .collect();
        format!(
            "the tiles are in {} CRSs: {}; a virtual point cloud's tiles should share one",
            distinct.len(),
            list.join(", ")
        )
    })
}

/// One input of a tiled conversion.
#[derive(Clone, Debug)]
pub struct Tile {
    pub input: PathBuf,
    /// Its distinct name ([`tile_names`]).
    pub name: String,
    /// `DIR/NAME.copc.laz`.
    pub out: PathBuf,
}

/// The tiles converting `inputs` into the folder `dir`.
pub fn plan(inputs: &[PathBuf], dir: &Path) -> Vec<Tile> {
    inputs
        .iter()
        .zip(tile_names(inputs))
        .map(|(input, name)| Tile {
            input: input.clone(),
            out: dir.join(format!("{name}{COPC_SUFFIX}")),
            name,
        })
        .collect()
}

/// A finished tile: its conversion's result and its seconds.
pub struct Done<'a> {
    pub tile: &'a Tile,
    pub result: Result<ConvertStats>,
    pub seconds: f64,
}

/// The default number of parallel jobs: one per core. Parts of a tile's conversion run on one
/// thread (reading a LAZ file, the octree's first levels, writing), so tiles side by side use
/// the cores better than one tile at a time on all of them (docs/measurements.md).
pub fn default_jobs() -> usize {
    cores()
}

fn cores() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get())
}

/// Converts every tile, `jobs` at a time (at most one per tile), each job with its own thread
/// pool of an equal share of the cores (all of them for one job). `finished` sees each tile as it ends, in the order
/// they end; a failed tile does not stop the others. When the options' stop flag is set, no
/// further tile starts. Returns the results in `tiles`' order (`None` for a tile not started).
pub fn convert_tiles<'a>(
    tiles: &'a [Tile],
    options: &ConvertOptions,
    jobs: usize,
    mut finished: impl FnMut(&Done<'a>),
) -> Vec<Option<Done<'a>>> {
    let jobs = jobs.clamp(1, tiles.len().max(1));
    let threads = (cores() / jobs).max(1);
    let next = AtomicUsize::new(0);
    let stopped = || options.stop.is_some_and(|s| s.load(Ordering::Relaxed));
    let mut results: Vec<Option<Done<'a>>> = tiles.iter().map(|_| None).collect();
    std::thread::scope(|scope| {
        let (send, receive) = mpsc::channel::<(usize, Done<'a>)>();
        for _ in 0..jobs {
            let send = send.clone();
            let (next, stopped) = (&next, &stopped);
            scope.spawn(move || {
                let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build();
                loop {
                    let i = next.fetch_add(1, Ordering::Relaxed);
                    if i >= tiles.len() || stopped() {
                        break;
                    }
                    let tile = &tiles[i];
                    let start = Instant::now();
                    let run = || convert::convert(&tile.input, &tile.out, options);
                    let result = match &pool {
                        Ok(pool) => pool.install(run),
                        Err(_) => run(),
                    };
                    let done = Done {
                        tile,
                        result,
                        seconds: start.elapsed().as_secs_f64(),
                    };
                    if send.send((i, done)).is_err() {
                        break;
                    }
                }
            });
        }
        drop(send);
        for (i, done) in receive {
            finished(&done);
            results[i] = Some(done);
        }
    });
    results
}

/// The CRS of `header` as a `.vpc` records it; `None` without one (an empty WKT record is
/// none).
fn vpc_crs(header: &las::Header) -> Option<Crs> {
    let vlrs = header
        .vlrs()
        .iter()
        .chain(header.evlrs())
        .filter(|v| !empty_wkt(v));
    Crs::of_vlrs(vlrs).filter(|c| *c != Crs::default())
}

/// The `.vpc` entry of the LAS, LAZ or COPC file `file` (from its header), its href relative
/// to the `.vpc` at `vpc`; its CRS is `source`'s (the file it was converted from) when `file`
/// records none.
pub fn summarize(vpc: &Path, file: &Path, source: Option<&Path>) -> Result<TileSummary> {
    let mut summary = vpc::summarize(vpc, file)?;
    summary.crs = las_header(file)
        .and_then(|h| vpc_crs(&h))
        .or_else(|| vpc_crs(&las_header(source?)?));
    Ok(summary)
}

/// The `.vpc` a tiled conversion into `dir` writes: `NAME.vpc` (a `.vpc` ending given with
/// `name` is not doubled), by default named after the folder.
pub fn vpc_path(dir: &Path, name: Option<&str>) -> PathBuf {
    let folder = || {
        std::path::absolute(dir)
            .ok()
            .and_then(|d| d.file_name().map(|n| n.to_string_lossy().into_owned()))
            .unwrap_or_else(|| "tiles".to_owned())
    };
    let name = name.map_or_else(folder, |n| n.strip_suffix(".vpc").unwrap_or(n).to_owned());
    dir.join(format!("{name}.vpc"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_formats_are_those_the_loaders_name() {
        assert_eq!(endings(&FORMATS), crate::scene::error::FORMATS);
    }
}
