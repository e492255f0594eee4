//! Converting many tiles: `surfel convert` over files, folders and glob patterns, one COPC file
//! per input with `--tiles` (every point kept, failures reported while the others convert), and
//! the errors for inputs that name nothing or a file twice and for CRSs a merge cannot mix.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use surfel::copc::tiles::{self, FORMATS};
use surfel::copc::vpc;
use surfel::scene::{self, Cloud};

/// A fresh folder for one test.
fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("surfel-tiles-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn surfel(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_surfel"))
        .args(args)
        .env("XDG_RUNTIME_DIR", std::env::temp_dir())
        .output()
        .expect("run surfel")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn text(p: &Path) -> &str {
    p.to_str().expect("utf8")
}

/// GeoTIFF keys (`LASF_Projection` 34735) naming the projected CRS `epsg`.
fn geotiff(epsg: u16) -> las::Vlr {
    let keys: [u16; 8] = [1, 1, 0, 1, 3072, 0, 1, epsg];
    las::Vlr {
        user_id: "LASF_Projection".into(),
        record_id: 34735,
        description: "GeoTIFF GeoKeyDirectoryTag".into(),
        data: keys.iter().flat_map(|k| k.to_le_bytes()).collect(),
    }
}

/// Writes a LAS tile of `n` points at `(x0, y0)` with every attribute varying: LAS 1.2 point
/// format 3 (colours) or 1 (none), with the projected CRS `epsg` when given.
fn write_tile(path: &Path, n: usize, x0: f64, colors: bool, epsg: Option<u16>) {
    let mut builder = las::Builder::from((1, 2));
    builder.point_format = las::point::Format::new(if colors { 3 } else { 1 }).unwrap();
    builder.transforms = las::Vector {
        x: las::Transform {
            scale: 0.001,
            offset: x0,
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
    builder.vlrs.extend(epsg.map(geotiff));
    let mut writer = las::Writer::from_path(path, builder.into_header().unwrap()).unwrap();
    for i in 0..n {
        let (u, v) = ((i % 25) as f64 * 0.5, (i / 25) as f64 * 0.5);
        writer
            .write_point(las::Point {
                x: x0 + u,
                y: 4_000_000.0 + v,
                z: 100.0 + (u * 0.3).sin() * 2.0 + v * 0.01,
                intensity: (i * 37 % 4000) as u16,
                return_number: (i % 3 + 1) as u8,
                number_of_returns: 3,
                classification: las::point::Classification::new((i % 6 + 1) as u8).unwrap(),
                point_source_id: 7,
                gps_time: Some(3.0e8 + x0 * 1e-3 + i as f64 * 0.01),
                color: colors.then(|| {
                    las::Color::new(
                        (i * 97 % 256) as u16 * 257,
                        (i * 31 % 256) as u16 * 257,
                        (i * 7 % 256) as u16 * 257,
                    )
                }),
                ..Default::default()
            })
            .unwrap();
    }
    writer.close().unwrap();
}

/// One point as the loaders read it: the position in millimetres, the colour, then intensity,
/// classification, return number, number of returns, point source id and the GPS time in
/// milliseconds (loaded as f32 seconds after a file's earliest time, they agree to the
/// millisecond whatever that earliest time is).
type Record = ([i64; 3], [u8; 4], [i64; 6]);

/// `cloud`'s points as [`Record`]s, sorted.
fn records(cloud: &Cloud) -> Vec<Record> {
    let field = |name: &str| {
        &cloud
            .scalars
            .iter()
            .find(|s| s.name == name)
            .unwrap_or_else(|| panic!("no field {name}"))
            .values
    };
    let origin = cloud.stats.gps_time_origin.unwrap_or(0.0);
    let names = [
        "intensity",
        "classification",
        "return_number",
        "number_of_returns",
        "point_source_id",
    ];
    let mut out: Vec<Record> = (0..cloud.len())
        .map(|i| {
            let w = cloud.origin + cloud.positions[i].as_dvec3();
            let mut values = [0i64; 6];
            for (v, name) in values.iter_mut().zip(names) {
                *v = field(name)[i] as i64;
            }
            values[5] = ((f64::from(field("gps_time")[i]) + origin) * 1e3).round() as i64;
            (
                [w.x, w.y, w.z].map(|v| (v * 1000.0).round() as i64),
                cloud.colors.as_ref().map_or([0; 4], |c| c[i]),
                values,
            )
        })
        .collect();
    out.sort_unstable();
    out
}

/// The bounds of a LAS file's header, as a `.vpc` lists them.
fn header_bounds(path: &Path) -> ([f64; 3], [f64; 3]) {
    let b = las::Reader::from_path(path).unwrap().header().bounds();
    ([b.min.x, b.min.y, b.min.z], [b.max.x, b.max.y, b.max.z])
}

/// Parses the `.vpc` at `path`.
fn read_vpc(path: &Path) -> vpc::Vpc {
    vpc::parse(text(path), &std::fs::read(path).unwrap()).unwrap_or_else(|e| panic!("{e:#}"))
}

/// The records of every file of `paths`, together, sorted.
fn union(paths: &[PathBuf]) -> Vec<Record> {
    let mut all: Vec<Record> = paths
        .iter()
        .flat_map(|p| records(&scene::load(p).unwrap_or_else(|e| panic!("{e}"))))
        .collect();
    all.sort_unstable();
    all
}

#[test]
fn tiles_are_converted_one_copc_file_each_keeping_every_point() {
    let dir = scratch("keep");
    let input = dir.join("in");
    std::fs::create_dir_all(&input).unwrap();
    let sizes = [("north", 600), ("south", 450), ("west", 300)];
    for (k, (name, n)) in sizes.iter().enumerate() {
        let x0 = 500_000.0 + 100.0 * k as f64;
        write_tile(
            &input.join(format!("{name}.las")),
            *n,
            x0,
            k != 1,
            Some(32610),
        );
    }
    // Not a point cloud: the folder contributes only its .las files.
    std::fs::write(input.join("notes.md"), "survey notes").unwrap();
    let out = dir.join("out");
    let o = surfel(&[
        "convert",
        text(&input),
        "--tiles",
        "--jobs",
        "2",
        "--node-points",
        "1000",
        "--out",
        text(&out),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let e = stderr(&o);
    let inputs: Vec<PathBuf> = sizes
        .iter()
        .map(|(name, _)| input.join(format!("{name}.las")))
        .collect();
    let outputs: Vec<PathBuf> = sizes
        .iter()
        .map(|(name, _)| out.join(format!("{name}.copc.laz")))
        .collect();
    for (k, ((name, n), (i, o))) in sizes.iter().zip(inputs.iter().zip(&outputs)).enumerate() {
        assert_eq!(
            union(std::slice::from_ref(i)),
            union(std::slice::from_ref(o)),
            "{name}"
        );
        assert_eq!(
            e.lines()
                .filter(|l| l.contains(&format!("] {name}: {n} points in ")))
                .count(),
            1,
            "tile {k}:\n{e}"
        );
    }
    assert_eq!(union(&inputs).len(), 1350);
    assert_eq!(union(&inputs), union(&outputs));
    let lines: Vec<&str> = e.lines().collect();
    assert!(
        lines[3].starts_with("3 of 3 tiles, 1350 points in ") && lines[3].contains(", 2 jobs) -> "),
        "{e}"
    );
    // The virtual point cloud is named after the folder and lists every tile, in input order.
    let list = out.join("out.vpc");
    assert_eq!(lines[4], format!("{}: 3 tiles", list.display()));
    assert_eq!(lines.len(), 5, "{e}");
    let v = read_vpc(&list);
    assert_eq!(v.tiles.len(), 3);
    for ((tile, (name, n)), file) in v.tiles.iter().zip(&sizes).zip(&outputs) {
        assert_eq!(tile.id, *name);
        assert_eq!(tile.href, format!("./{name}.copc.laz"));
        assert_eq!(Path::new(&tile.location), file.as_path());
        assert_eq!(tile.points, *n as u64);
        assert_eq!(tile.encoding, vpc::Encoding::Copc);
        // The converted tile records no CRS; the input's is listed.
        assert_eq!(tile.crs.as_ref().and_then(|c| c.epsg), Some(32610));
        let (lo, hi) = tile.bounds.expect("proj:bbox");
        assert_eq!((lo, hi), header_bounds(file));
        // Within a step of the 0.001 scale of the input's (written unquantized).
        let (ilo, ihi) = header_bounds(&input.join(format!("{name}.las")));
        for axis in 0..3 {
            assert!(
                (lo[axis] - ilo[axis]).abs() < 1.5e-3,
                "{name}: {lo:?} {ilo:?}"
            );
            assert!(
                (hi[axis] - ihi[axis]).abs() < 1.5e-3,
                "{name}: {hi:?} {ihi:?}"
            );
        }
    }
    assert_eq!(v.points(), 1350);
    // `surfel vpc` lists converted tiles again, from their headers, relative to its folder.
    let again = dir.join("again.vpc");
    let o = surfel(&["vpc", text(&out.join("*.copc.laz")), "--out", text(&again)]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(
        stderr(&o),
        format!("{}: 3 files, 1350 points\n", again.display())
    );
    let w = read_vpc(&again);
    let hrefs: Vec<&str> = w.tiles.iter().map(|t| t.href.as_str()).collect();
    assert_eq!(
        hrefs,
        [
            "./out/north.copc.laz",
            "./out/south.copc.laz",
            "./out/west.copc.laz"
        ]
    );
    for (a, b) in v.tiles.iter().zip(&w.tiles) {
        assert_eq!(
            (a.location.as_str(), a.points, a.bounds),
            (b.location.as_str(), b.points, b.bounds)
        );
    }
    // A merge of the folder into one of its files is refused.
    let north = out.join("north.copc.laz");
    let o = surfel(&["convert", text(&out), "--out", text(&north)]);
    assert_eq!(o.status.code(), Some(1));
    assert_eq!(
        stderr(&o),
        format!(
            "error: {}: the output is also one of the 3 inputs; choose another --out\n",
            north.display()
        )
    );
    let o = surfel(&["vpc", text(&out), "--out", text(&dir.join("all.json"))]);
    assert_eq!(
        stderr(&o),
        format!(
            "error: {}: a virtual point cloud's name ends in .vpc (readers choose the format by it)\n",
            dir.join("all.json").display()
        )
    );
    // Nothing else: no staging folder or temporary file is left behind.
    let mut written: Vec<String> = std::fs::read_dir(&out)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    written.sort();
    assert_eq!(
        written,
        [
            "north.copc.laz",
            "out.vpc",
            "south.copc.laz",
            "west.copc.laz"
        ]
    );
    std::fs::remove_dir_all(dir).unwrap();
}

#[test]
fn a_corrupt_tile_is_reported_and_the_others_converted() {
    let dir = scratch("corrupt");
    let input = dir.join("in");
    std::fs::create_dir_all(&input).unwrap();
    write_tile(&input.join("a.las"), 200, 500_000.0, true, None);
    std::fs::write(input.join("b.las"), b"junk, not a LAS file").unwrap();
    write_tile(&input.join("c.las"), 150, 500_100.0, true, None);
    let out = dir.join("out");
    let o = surfel(&[
        "convert",
        text(&input.join("*.las")),
        "--tiles",
        "--jobs",
        "1",
        "--vpc",
        "survey",
        "--out",
        text(&out),
    ]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let e = stderr(&o);
    let bad = input.join("b.las");
    let lines: Vec<&str> = e.lines().collect();
    // One job: the tiles finish in input order.
    assert!(lines[0].starts_with("[1/3] a: 200 points in "), "{e}");
    assert_eq!(
        lines[1],
        format!(
            "[2/3] b: failed: {}: byte offset 0: expected the LAS signature \"LASF\", found \"junk\"",
            bad.display()
        )
    );
    assert!(lines[2].starts_with("[3/3] c: 150 points in "), "{e}");
    assert!(lines[3].starts_with("2 of 3 tiles, 350 points in "), "{e}");
    let list = out.join("survey.vpc");
    assert_eq!(lines[4], format!("{}: 2 tiles", list.display()));
    assert_eq!(
        lines[5],
        format!("error: 1 of 3 tiles failed: {}", bad.display())
    );
    assert_eq!(lines.len(), 6, "{e}");
    let ids: Vec<String> = read_vpc(&list).tiles.into_iter().map(|t| t.id).collect();
    assert_eq!(ids, ["a", "c"]);
    // The failed tile left nothing behind (no staging folder, no temporary file).
    let mut written: Vec<String> = std::fs::read_dir(&out)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    written.sort();
    assert_eq!(written, ["a.copc.laz", "c.copc.laz", "survey.vpc"]);
    assert_eq!(
        union(&[input.join("a.las"), input.join("c.las")]),
        union(&[out.join("a.copc.laz"), out.join("c.copc.laz")])
    );
    assert!(!out.join("b.copc.laz").exists());
    std::fs::remove_dir_all(dir).unwrap();
}

#[test]
fn folders_and_patterns_expand_to_their_point_cloud_files() {
    let dir = scratch("expand");
    let sub = dir.join("sub");
    std::fs::create_dir_all(&sub).unwrap();
    for name in ["b.las", "a.laz", "c.copc.laz", "readme.md"] {
        std::fs::write(dir.join(name), b"").unwrap();
    }
    std::fs::write(sub.join("d.las"), b"").unwrap();
    let names = |files: Vec<PathBuf>| -> Vec<String> {
        files
            .iter()
            .map(|f| f.strip_prefix(&dir).unwrap().to_string_lossy().into_owned())
            .collect()
    };
    let expand = |args: &[PathBuf], recursive| tiles::expand(args, &FORMATS, recursive);
    assert_eq!(
        names(expand(std::slice::from_ref(&dir), false).unwrap()),
        ["a.laz", "b.las", "c.copc.laz"]
    );
    // A link back up is not followed.
    std::os::unix::fs::symlink(&dir, sub.join("up")).unwrap();
    assert_eq!(
        names(expand(std::slice::from_ref(&dir), true).unwrap()),
        ["a.laz", "b.las", "c.copc.laz", "sub/d.las"]
    );
    // A pattern, as a shell passes it on quoted, and files as they are, in the order given.
    assert_eq!(
        names(expand(&[dir.join("*.la?"), dir.join("sub/d.las")], false).unwrap()),
        ["a.laz", "b.las", "c.copc.laz", "sub/d.las"]
    );
    assert_eq!(
        names(expand(&[dir.join("*/*.las"), dir.join("c.copc.laz")], false).unwrap()),
        ["sub/d.las", "c.copc.laz"]
    );
    let error = |args: &[PathBuf], recursive| expand(args, recursive).unwrap_err().to_string();
    let all = surfel::scene::error::FORMATS;
    assert_eq!(
        error(&[dir.join("missing.las")], false),
        format!(
            "{}: no such file or folder",
            dir.join("missing.las").display()
        )
    );
    assert_eq!(
        error(&[dir.join("*.e57")], false),
        format!(
            "{}: the pattern matches no point-cloud file ({all})",
            dir.join("*.e57").display()
        )
    );
    let empty = dir.join("empty");
    std::fs::create_dir_all(empty.join("deeper")).unwrap();
    assert_eq!(
        error(std::slice::from_ref(&empty), false),
        format!(
            "{}: the folder holds no point-cloud file ({all}); --recursive searches its subfolders too",
            empty.display()
        )
    );
    assert_eq!(
        error(std::slice::from_ref(&empty), true),
        format!(
            "{}: the folder holds no point-cloud file ({all})",
            empty.display()
        )
    );
    assert_eq!(
        error(&[dir.clone(), dir.join("sub/../b.las")], false),
        format!(
            "{}: given twice (first as {}); each input is converted once",
            dir.join("sub/../b.las").display(),
            dir.join("b.las").display()
        )
    );
    let only_copc = tiles::expand(std::slice::from_ref(&dir), &["copc.laz"], false).unwrap();
    assert_eq!(names(only_copc), ["c.copc.laz"]);
    assert_eq!(
        tiles::expand(std::slice::from_ref(&sub), &["copc.laz"], false)
            .unwrap_err()
            .to_string(),
        format!(
            "{}: the folder holds no point-cloud file (.copc.laz); --recursive searches its subfolders too",
            sub.display()
        )
    );
    // The command line stops on the same errors, before converting anything.
    let o = surfel(&[
        "convert",
        text(&dir.join("*.e57")),
        "--out",
        text(&dir.join("x.copc.laz")),
    ]);
    assert_eq!(o.status.code(), Some(1));
    assert_eq!(
        stderr(&o),
        format!(
            "error: {}: the pattern matches no point-cloud file ({all})\n",
            dir.join("*.e57").display()
        )
    );
    std::fs::remove_dir_all(dir).unwrap();
}

#[test]
fn tiles_sharing_a_name_are_named_apart() {
    let names = |paths: &[&str]| {
        let paths: Vec<PathBuf> = paths.iter().map(PathBuf::from).collect();
        tiles::tile_names(&paths)
    };
    assert_eq!(
        names(&["a/x.las", "b/x.laz", "c/y.copc.laz", "z"]),
        ["a-x", "b-x", "y", "z"]
    );
    // Case differences collide too (object stores and some file systems merge them); a shared
    // folder name falls back to numbers.
    assert_eq!(
        names(&["p/a/X.las", "q/a/x.las", "r/b/x.las"]),
        ["a-X", "a-x-2", "b-x"]
    );
    assert_eq!(
        names(&["t/x.las", "t/x.laz", "t-x.las"]),
        ["t-x", "t-x-2", "t-x-3"]
    );
    assert_eq!(
        tiles::vpc_path(Path::new("out/city"), None),
        Path::new("out/city/city.vpc")
    );
    assert_eq!(
        tiles::vpc_path(Path::new("out"), Some("all.vpc")),
        Path::new("out/all.vpc")
    );
    let tiles = tiles::plan(
        &[PathBuf::from("a/x.las"), PathBuf::from("b/x.las")],
        Path::new("out"),
    );
    assert_eq!(tiles[1].out, Path::new("out/b-x.copc.laz"));
}

#[test]
fn a_merge_of_inputs_in_two_crss_is_refused() {
    let dir = scratch("crs");
    let (a, b, c) = (dir.join("a.las"), dir.join("b.las"), dir.join("c.las"));
    write_tile(&a, 50, 500_000.0, true, Some(32610));
    write_tile(&b, 50, 500_100.0, true, Some(32611));
    write_tile(&c, 50, 500_200.0, true, None);
    let o = surfel(&[
        "convert",
        text(&dir),
        "--out",
        text(&dir.join("all.copc.laz")),
    ]);
    assert_eq!(o.status.code(), Some(1));
    assert_eq!(
        stderr(&o),
        format!(
            "error: {} has the CRS projected EPSG:32610 (GeoTIFF keys), {} has projected \
             EPSG:32611 (GeoTIFF keys): a merged COPC file has one CRS (reproject them to one, \
             or convert them apart with --tiles)\n",
            a.display(),
            b.display()
        )
    );
    assert!(!dir.join("all.copc.laz").exists());
    assert_eq!(
        tiles::check_one_crs(&[a.clone(), c.clone()]).unwrap(),
        Some(format!(
            "1 of 2 inputs record no CRS; the output is taken to be in {}'s, projected \
             EPSG:32610 (GeoTIFF keys)",
            a.display()
        ))
    );
    // Tiles may differ, with a warning.
    let out = dir.join("tiles");
    let o = surfel(&["convert", text(&dir), "--tiles", "--out", text(&out)]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(
        stderr(&o).lines().next().unwrap_or_default(),
        format!(
            "warning: the tiles are in 3 CRSs: projected EPSG:32610 (GeoTIFF keys) ({}), \
             projected EPSG:32611 (GeoTIFF keys) ({}), none ({}); a virtual point cloud's \
             tiles should share one",
            a.display(),
            b.display(),
            c.display()
        )
    );
    // `surfel vpc` lists LAS files as they are, with the same warning and each file's CRS.
    let list = dir.join("las.vpc");
    let o = surfel(&["vpc", text(&a), text(&b), text(&c), "--out", text(&list)]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stderr(&o).starts_with("warning: the tiles are in 3 CRSs: projected EPSG:32610"),
        "{}",
        stderr(&o)
    );
    let v = read_vpc(&list);
    let listed: Vec<(String, Option<u32>, vpc::Encoding)> = v
        .tiles
        .iter()
        .map(|t| {
            (
                t.href.clone(),
                t.crs.as_ref().and_then(|c| c.epsg),
                t.encoding,
            )
        })
        .collect();
    assert_eq!(
        listed,
        [
            ("./a.las".to_owned(), Some(32610), vpc::Encoding::Las),
            ("./b.las".to_owned(), Some(32611), vpc::Encoding::Las),
            ("./c.las".to_owned(), None, vpc::Encoding::Las),
        ]
    );
    std::fs::remove_dir_all(dir).unwrap();
}

#[test]
fn tiles_merged_into_one_copc_file_keep_every_point() {
    let dir = scratch("merge");
    let input = dir.join("in");
    std::fs::create_dir_all(&input).unwrap();
    let sizes = [("a", 400), ("b", 350), ("c", 250)];
    for (k, (name, n)) in sizes.iter().enumerate() {
        let x0 = 500_000.0 + 100.0 * k as f64;
        write_tile(
            &input.join(format!("{name}.las")),
            *n,
            x0,
            k != 1,
            Some(32610),
        );
    }
    let out = dir.join("all.copc.laz");
    let o = surfel(&[
        "convert",
        text(&input.join("*.las")),
        "--node-points",
        "1000",
        "--out",
        text(&out),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let inputs: Vec<PathBuf> = sizes
        .iter()
        .map(|(name, _)| input.join(format!("{name}.las")))
        .collect();
    // The merged file has colours, since two inputs do: the third's points are black.
    let mut expected: Vec<Record> = union(&inputs)
        .into_iter()
        .map(|(p, c, v)| (p, if c[3] == 0 { [0, 0, 0, 255] } else { c }, v))
        .collect();
    expected.sort_unstable();
    assert_eq!(expected.len(), 1000);
    assert_eq!(union(std::slice::from_ref(&out)), expected);
    // Its header's bounds are those of the tiles together, within a step of the 0.001 scale.
    let (lo, hi) = header_bounds(&out);
    for axis in 0..3 {
        let lows = inputs.iter().map(|i| header_bounds(i).0[axis]);
        let highs = inputs.iter().map(|i| header_bounds(i).1[axis]);
        let (ilo, ihi) = (
            lows.fold(f64::MAX, f64::min),
            highs.fold(f64::MIN, f64::max),
        );
        assert!((lo[axis] - ilo).abs() < 1.5e-3, "{lo:?} {ilo}");
        assert!((hi[axis] - ihi).abs() < 1.5e-3, "{hi:?} {ihi}");
    }
    std::fs::remove_dir_all(dir).unwrap();
}
