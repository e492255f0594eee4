//! Conversion to COPC and streaming from it: what is written reads back (through this
//! project's COPC reader and, independently, the `las` crate reading it as plain LAZ 1.4).

use std::path::{Path, PathBuf};

use glam::{DVec3, Vec3};
use surfel::copc::convert;
use surfel::copc::select::{
    select, select_brute_force, select_forest, Budget, Hierarchy, SelectView, Tree,
};
use surfel::scene::copc::{CopcFile, Entry, Info, Key, Node};
use surfel::scene::{self, Cloud, Scalar};
use surfel::source::FileSource;

use crate::common;

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("surfel-stream-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

/// A UTM-sized cloud of `n` points on a wavy sheet with every attribute a conversion keeps.
fn survey(n: usize) -> Cloud {
    let side = (n as f64).sqrt().ceil() as usize;
    let positions: Vec<Vec3> = (0..n)
        .map(|i| {
            let (u, v) = ((i % side) as f32 * 0.25, (i / side) as f32 * 0.25);
            Vec3::new(u, v, (u * 0.3).sin() + (v * 0.2).cos())
        })
        .collect();
    let scalar = |name: &str, f: &dyn Fn(usize) -> f32| Scalar {
        name: name.into(),
        values: (0..n).map(f).collect(),
    };
    Cloud {
        normals: Some(
            positions
                .iter()
                .map(|p| Vec3::new(p.x.sin(), 1.0, p.y.cos()).normalize())
                .collect(),
        ),
        radii: Some((0..n).map(|i| 0.1 + (i % 7) as f32 * 0.01).collect()),
        colors: Some(
            (0..n)
                .map(|i| [(i % 256) as u8, (i / 7 % 256) as u8, 200, 255])
                .collect(),
        ),
        scalars: vec![
            scalar("intensity", &|i| (i * 37 % 65536) as f32),
            scalar("classification", &|i| (i % 12) as f32),
            scalar("return_number", &|i| (i % 3 + 1) as f32),
            scalar("number_of_returns", &|_| 3.0),
            scalar("gps_time", &|i| i as f32 * 0.5),
            scalar("quality", &|i| i as f32 * 0.25),
        ],
        positions,
        origin: DVec3::new(500_000.0, 4_000_000.0, 100.0),
        ..Cloud::default()
    }
}

/// Points keyed by their real-world x and y (on the survey's 0.25 grid, so rounding to 0.01 is
/// exact), with their real-world z and index.
fn by_position(cloud: &Cloud) -> Vec<([i64; 2], f64, usize)> {
    let mut keyed: Vec<([i64; 2], f64, usize)> = cloud
        .positions
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let w = cloud.origin + p.as_dvec3();
            ([w.x, w.y].map(|c| (c * 100.0).round() as i64), w.z, i)
        })
        .collect();
    keyed.sort_by_key(|k| k.0);
    keyed
}

fn scalar<'a>(cloud: &'a Cloud, name: &str) -> &'a [f32] {
    &cloud
        .scalars
        .iter()
        .find(|s| s.name == name)
        .unwrap_or_else(|| panic!("no scalar {name}"))
        .values
}

#[test]
fn conversion_keeps_every_point_and_attribute() {
    let cloud = survey(20_000);
    let out = scratch("survey.copc.laz");
    convert::write_with(&cloud, &out, 2_000).unwrap();
    let back = scene::load(&out).unwrap();
    assert_eq!(back.len(), cloud.len());
    let (a, b) = (by_position(&cloud), by_position(&back));
    for ((ka, za, ia), (kb, zb, ib)) in a.iter().zip(&b) {
        assert_eq!(ka, kb, "positions differ");
        // f32 offsets from two origins, quantized at 1e-5 in the file.
        assert!((za - zb).abs() < 2e-5, "z {za} vs {zb}");
        let (ia, ib) = (*ia, *ib);
        assert_eq!(
            cloud.colors.as_ref().unwrap()[ia],
            back.colors.as_ref().unwrap()[ib]
        );
        for name in [
            "intensity",
            "classification",
            "return_number",
            "number_of_returns",
            "quality",
        ] {
            assert_eq!(scalar(&cloud, name)[ia], scalar(&back, name)[ib], "{name}");
        }
        // GPS times come back relative to the earliest.
        assert_eq!(
            scalar(&cloud, "gps_time")[ia],
            scalar(&back, "gps_time")[ib]
        );
        let (na, nb) = (
            cloud.normals.as_ref().unwrap()[ia],
            back.normals.as_ref().unwrap()[ib],
        );
        // Normals are stored as two 16-bit octahedral coordinates, radii in 16 bits.
        let degrees = na.dot(nb).clamp(-1.0, 1.0).acos().to_degrees();
        assert!(degrees < 0.05, "{na} vs {nb}: {degrees}°");
        let (ra, rb) = (
            cloud.radii.as_ref().unwrap()[ia],
            back.radii.as_ref().unwrap()[ib],
        );
        assert!((ra - rb).abs() <= 0.005 * ra, "radius {ra} vs {rb}");
    }
}

/// The written file is a COPC file by the specification's rules, and plain LAZ 1.4 to a
/// reader that knows nothing of COPC.
#[test]
fn converted_file_is_valid_copc_and_laz() {
    let cloud = survey(30_000);
    let out = scratch("valid.copc.laz");
    convert::write_with(&cloud, &out, 1_000).unwrap();
    let bytes = std::fs::read(&out).unwrap();
    // The COPC info VLR is the first VLR, right after the 375-byte header.
    assert_eq!(&bytes[375 + 2..375 + 6], b"copc");
    assert_eq!(u16::from_le_bytes([bytes[375 + 18], bytes[375 + 19]]), 1);
    let source = FileSource::open(&out).unwrap();
    let copc = CopcFile::open(&source).unwrap();
    let mut pages = vec![copc.info.root];
    let mut total = 0;
    let mut keys = std::collections::HashSet::new();
    let mut nodes = Vec::new();
    while let Some((at, len)) = pages.pop() {
        for entry in scene::copc::read_page(&copc.file, &source, at, len, copc.size).unwrap() {
            match entry {
                Entry::Node(n) => {
                    total += n.points;
                    assert!(keys.insert(n.key), "{} twice", n.key);
                    nodes.push(n);
                }
                Entry::Page { offset, bytes, .. } => pages.push((offset, bytes)),
            }
        }
    }
    assert_eq!(total, cloud.len() as u64);
    assert!(nodes.len() > 8, "{} nodes", nodes.len());
    // Every node but the root has its parent, and its points lie in its cube.
    let slack = 1e-3;
    for n in &nodes {
        if n.key != Key::ROOT {
            assert!(keys.contains(&n.key.parent()), "{} without a parent", n.key);
        }
        let (lo, hi) = copc.info.cube(n.key);
        for p in copc.read_node(&source, n).unwrap().world {
            assert!(
                p.cmpge(lo - slack).all() && p.cmple(hi + slack).all(),
                "{p} outside {} ({lo} .. {hi})",
                n.key
            );
        }
    }
    // The `las` crate reads it as LAZ: the same number of points, in the same bounds.
    let mut reader = las::Reader::from_path(&out).unwrap();
    let points = reader.read_all().unwrap();
    assert_eq!(points.len(), cloud.len());
    let (lo, hi) = cloud.bounds().unwrap();
    for p in points.points() {
        let p = p.unwrap();
        let local = (DVec3::new(p.x, p.y, p.z) - cloud.origin).as_vec3();
        assert!(local.cmpge(lo - 1e-3).all() && local.cmple(hi + 1e-3).all());
    }
}

#[test]
fn conversion_refuses_what_it_cannot_write() {
    let cloud = survey(100);
    let m = convert::write_with(&cloud, Path::new("/nonexistent-dir/x.copc.laz"), 1000)
        .unwrap_err()
        .to_string();
    assert!(m.contains("/nonexistent-dir/x.copc.laz"), "{m}");
    let m = convert::convert(
        Path::new("../shared/data/stanford/bun_zipper.ply"),
        &scratch("bunny.laz"),
        &convert::ConvertOptions::default(),
    )
    .unwrap_err()
    .to_string();
    assert!(m.contains("ends in .copc.laz"), "{m}");
}

/// A full octree of `depth` levels over [-8, 8]^3 whose nodes hold pseudo-random point
/// counts (some empty), with the deepest level's entries behind unread pages.
fn octree(depth: i32) -> (Hierarchy, Info) {
    let info = Info {
        center: DVec3::ZERO,
        halfsize: 8.0,
        spacing: 0.5,
        root: (0, 0),
        gps_time: (0.0, 0.0),
    };
    let mut h = Hierarchy::default();
    let mut entries = Vec::new();
    let mut state = 12345u64;
    for level in 0..depth {
        let n = 1 << level;
        for x in 0..n {
            for y in 0..n {
                for z in 0..n {
                    state = state
                        .wrapping_mul(6364136223846793005)
                        .wrapping_add(1442695040888963407);
                    let points = (state >> 33) % 30_000;
                    let key = Key { level, x, y, z };
                    if level > 0 && points < 3_000 {
                        continue;
                    }
                    entries.push(Entry::Node(Node {
                        key,
                        offset: 0,
                        bytes: 1,
                        points: points.max(1),
                        entry_at: 0,
                    }));
                }
            }
        }
    }
    for x in 0..(1 << depth) {
        entries.push(Entry::Page {
            key: Key {
                level: depth,
                x,
                y: 1 << (depth - 1),
                z: 1 << (depth - 1),
            },
            offset: 1 + x as u64,
            bytes: 32,
        });
    }
    assert!(h.add_page(0, entries));
    (h, info)
}

fn view(eye: Vec3, target: Vec3, error_px: f32) -> SelectView {
    let proj = glam::Mat4::perspective_infinite_reverse_rh(60f32.to_radians(), 1.5, 0.01);
    let look = glam::Mat4::look_at_rh(eye, target, Vec3::Z);
    SelectView {
        view_proj: proj * look,
        eye,
        pixels_per_radian: 540.0 / (30f32.to_radians().tan()),
        error_px,
    }
}

#[test]
fn node_selection_matches_a_brute_force_reference_within_budget() {
    let (h, info) = octree(5);
    let views = [
        view(Vec3::new(30.0, 0.0, 5.0), Vec3::ZERO, 1.0),
        view(Vec3::new(2.0, 1.0, 0.5), Vec3::new(-5.0, 0.0, 0.0), 1.0),
        view(Vec3::new(0.0, 0.0, 0.0), Vec3::new(0.0, 8.0, 0.0), 2.0),
        view(Vec3::new(-7.0, -7.0, 7.0), Vec3::new(7.0, 7.0, -7.0), 0.5),
        view(Vec3::new(200.0, 0.0, 0.0), Vec3::ZERO, 1.0),
    ];
    let mut sizes = Vec::new();
    for v in &views {
        for (points, slots) in [
            (50_000, 1000),
            (400_000, 1000),
            (2_000_000, 60),
            (u64::MAX, u64::MAX),
            (1, 1000),
        ] {
            let budget = Budget { points, slots };
            let fast = select(&h, &info, DVec3::ZERO, v, budget);
            let slow = select_brute_force(&h, &info, DVec3::ZERO, v, budget);
            assert_eq!(fast, slow, "budget {budget:?}");
            // A budget below the root still draws the root, alone.
            let root = h.nodes[&Key::ROOT].points;
            assert!(fast.points <= points.max(root) && fast.slots <= slots);
            if points < root {
                assert_eq!(fast.nodes, [Key::ROOT]);
            }
            let sum: u64 = fast.nodes.iter().map(|k| h.nodes[k].points).sum();
            assert_eq!(sum, fast.points);
            let chosen: std::collections::HashSet<_> = fast.nodes.iter().collect();
            for k in &fast.nodes {
                assert!(
                    *k == Key::ROOT || chosen.contains(&k.parent()),
                    "{k} without its parent"
                );
            }
            sizes.push(fast.nodes.len());
        }
    }
    // The views and budgets select differently, and some reach the unread pages.
    let distinct: std::collections::HashSet<_> = sizes.iter().collect();
    assert!(distinct.len() > 6, "{sizes:?}");
    let unbounded = select(
        &h,
        &info,
        DVec3::ZERO,
        &views[1],
        Budget {
            points: u64::MAX,
            slots: u64::MAX,
        },
    );
    assert!(!unbounded.pages.is_empty());
    // A far view stops where the spacing projects below the error: the root's spacing of 0.5
    // at 200 units is 2.3 px, level 1's 1.2 px, level 2's 0.6 px.
    let far = select(
        &h,
        &info,
        DVec3::ZERO,
        &views[4],
        Budget {
            points: u64::MAX,
            slots: u64::MAX,
        },
    );
    assert_eq!(far.nodes.iter().map(|k| k.level).max(), Some(2));
}

/// A loopback HTTP/1.1 server for one file, answering `Range` requests (one request per
/// connection). `fault(at, attempt)` may replace the answer to the `attempt`-th request
/// (from 0) for a range starting at byte `at` with a status code, or with silence (0).
mod http {
    use std::collections::HashMap;
    use std::io::{BufRead, BufReader, Write};
    use std::net::TcpListener;
    use std::sync::{Arc, Mutex};

    pub type Fault = dyn Fn(u64, u32) -> Option<u16> + Send + Sync;

    pub struct Server {
        pub url: String,
        pub requests: Arc<Mutex<u64>>,
    }

    pub fn serve(bytes: Vec<u8>, fault: Box<Fault>) -> Server {
        let listener = TcpListener::bind("127.0.0.1:0").unwrap();
        let url = format!("http://{}/cloud.copc.laz", listener.local_addr().unwrap());
        let requests = Arc::new(Mutex::new(0));
        let count = requests.clone();
        let (bytes, fault) = (Arc::new(bytes), Arc::new(fault));
        let attempts = Arc::new(Mutex::new(HashMap::<u64, u32>::new()));
        std::thread::spawn(move || {
            for stream in listener.incoming() {
                let Ok(mut stream) = stream else { continue };
                let (bytes, fault, attempts) = (bytes.clone(), fault.clone(), attempts.clone());
                *count.lock().unwrap() += 1;
                std::thread::spawn(move || {
                    let mut reader = BufReader::new(stream.try_clone().unwrap());
                    let mut line = String::new();
                    reader.read_line(&mut line).unwrap_or(0);
                    let path = line.split_whitespace().nth(1).unwrap_or("").to_owned();
                    let mut range = None;
                    loop {
                        let mut h = String::new();
                        if reader.read_line(&mut h).unwrap_or(0) == 0 || h.trim().is_empty() {
                            break;
                        }
                        let lower = h.to_ascii_lowercase();
                        if let Some(r) = lower.strip_prefix("range: bytes=") {
                            let (a, b) = r.trim().split_once('-').unwrap();
                            range = Some((a.parse::<u64>().unwrap(), b.parse::<u64>().unwrap()));
                        }
                    }
                    let reply = |stream: &mut std::net::TcpStream,
                                 status: &str,
                                 headers: String,
                                 body: &[u8]| {
                        let head = format!(
                            "HTTP/1.1 {status}\r\nContent-Length: {}\r\nConnection: close\r\n{headers}\r\n",
                            body.len()
                        );
                        let _ = stream.write_all(head.as_bytes());
                        let _ = stream.write_all(body);
                    };
                    if path != "/cloud.copc.laz" {
                        return reply(&mut stream, "404 Not Found", String::new(), b"no such file");
                    }
                    let Some((a, b)) = range else {
                        return reply(&mut stream, "200 OK", String::new(), &bytes);
                    };
                    let attempt = {
                        let mut map = attempts.lock().unwrap();
                        let n = map.entry(a).or_insert(0);
                        *n += 1;
                        *n - 1
                    };
                    match fault(a, attempt) {
                        // 0: no answer for longer than the client waits, then the connection closes.
                        Some(0) => {
                            std::thread::sleep(std::time::Duration::from_millis(1500));
                            return;
                        }
                        Some(code) => {
                            return reply(
                                &mut stream,
                                &format!("{code} Injected"),
                                String::new(),
                                b"",
                            );
                        }
                        None => {}
                    }
                    let end = (b as usize).min(bytes.len() - 1);
                    reply(
                        &mut stream,
                        "206 Partial Content",
                        format!("Content-Range: bytes {a}-{end}/{}\r\n", bytes.len()),
                        &bytes[a as usize..=end],
                    );
                });
            }
        });
        Server { url, requests }
    }
}

mod gpu {
    use std::time::Duration;

    use surfel::color;
    use surfel::copc::loader::LoaderOptions;
    use surfel::frame::Frame;
    use surfel::gpu_scene::streamed::{StreamOptions, StreamStats, StreamedScene};
    use surfel::methods::MethodConfig;
    use surfel::render::{Renderer, RendererOptions, View};
    use surfel::scene::{Camera, Up};
    use surfel::source::HttpOptions;

    use super::*;

    /// The dragon as a COPC of many small nodes (converted once per test process).
    pub fn dragon() -> PathBuf {
        static ONCE: std::sync::OnceLock<PathBuf> = std::sync::OnceLock::new();
        ONCE.get_or_init(|| {
            let cloud = scene::load(Path::new("../shared/data/stanford/dragon_vrip.ply")).unwrap();
            let out = scratch("dragon.copc.laz");
            convert::write_with(&cloud, &out, 8_000).unwrap();
            out
        })
        .clone()
    }

    pub fn options(point_budget: u64, gpu_bytes: u64, error_px: f32) -> StreamOptions {
        StreamOptions {
            point_budget,
            gpu_bytes,
            error_px,
            loader: LoaderOptions {
                threads: 2,
                k: 0,
                scalar: None,
                normal_field: false,
                http: HttpOptions {
                    attempts: 4,
                    backoff: Duration::from_millis(5),
                    timeout: Duration::from_secs(10),
                    connections: 8,
                },
            },
        }
    }

    pub struct Streamed {
        pub frame: Frame,
        pub stats: StreamStats,
        pub messages: Vec<String>,
    }

    /// Streams `location` through `cameras` in turn (each until its choice is resident; a
    /// camera from the framing sphere) and returns the last view's frame, `points`, elevation.
    pub fn stream(
        location: &str,
        options: &StreamOptions,
        cameras: &[&dyn Fn(Vec3, f32) -> Camera],
        size: u32,
    ) -> Streamed {
        let ctx = common::context();
        let mut s = StreamedScene::open(
            &ctx,
            location,
            options,
            |root| Ok(color::select(root, "elevation", Up::Z).unwrap()),
            2,
        )
        .unwrap();
        let config = MethodConfig::parse("points").unwrap();
        let mut r = Renderer::new(
            &ctx,
            &s.scene,
            s.info,
            &config,
            size,
            size,
            RendererOptions {
                readback: true,
                frames_in_flight: 2,
                ..RendererOptions::default()
            },
        )
        .unwrap();
        let (centre, radius) = s.bounding_sphere();
        let mut frame = None;
        let mut messages = Vec::new();
        for make in cameras {
            let camera = make(centre, radius);
            let view = View {
                camera,
                lights: Vec::new(),
                use_color: true,
                time: 0.0,
            };
            for round in 0.. {
                assert!(round < 2000, "streaming never settled");
                s.update(&camera, size, size).unwrap();
                let stats = s.stats();
                // The root alone may exceed the budget: it is drawn whatever the budget.
                assert!(stats.selected_points <= options.point_budget || stats.selected_nodes == 1);
                assert!(stats.used_slots <= stats.slots);
                // Frames are drawn while nodes arrive, as the viewer does.
                r.render_batches(&view, Some(s.batches()), false).unwrap();
                if s.stable() {
                    break;
                }
                s.wait(Duration::from_millis(50));
            }
            frame = r.render_batches(&view, Some(s.batches()), true).unwrap();
            messages.extend(s.take_messages());
        }
        drop(r);
        common::assert_clean(&ctx);
        Streamed {
            frame: frame.unwrap(),
            stats: s.stats(),
            messages,
        }
    }

    pub fn framing(c: Vec3, r: f32) -> Camera {
        Camera::framing(c, r)
    }

    /// Pixels whose coverage differs, as a fraction.
    pub fn coverage_difference(a: &Frame, b: &Frame) -> f64 {
        (0..a.pixels())
            .filter(|&i| a.covered(i) != b.covered(i))
            .count() as f64
            / a.pixels() as f64
    }
}

#[test]
fn streaming_everything_matches_the_loaded_file() {
    let path = gpu::dragon();
    let all = gpu::stream(
        path.to_str().unwrap(),
        &gpu::options(u64::MAX, 256 << 20, 0.0),
        &[&gpu::framing],
        256,
    );
    assert!(all.messages.is_empty(), "{:?}", all.messages);
    assert_eq!(all.stats.drawn_points, 437_645);
    assert!(
        all.stats.selected_nodes > 40,
        "{}",
        all.stats.selected_nodes
    );
    let cloud = scene::load(&path).unwrap();
    let coloring = surfel::color::select(&cloud, "elevation", surfel::scene::Up::Z).unwrap();
    let loaded = common::render_colored(&cloud, "points", 256, coloring);
    let differ = gpu::coverage_difference(&all.frame, &loaded);
    assert!(differ < 0.002, "{differ}");
    assert!(common::coverage(&loaded) > 0.2);
}

/// A budget that makes the view choose part of the octree.
const PART: u64 = 150_000;

/// The root node's point count in the COPC file at `path`.
fn root_points(path: &Path) -> u64 {
    let source = FileSource::open(path).unwrap();
    let copc = CopcFile::open(&source).unwrap();
    let (at, len) = copc.info.root;
    scene::copc::read_page(&copc.file, &source, at, len, copc.size)
        .unwrap()
        .into_iter()
        .find_map(|e| match e {
            Entry::Node(n) if n.key == Key::ROOT => Some(n.points),
            _ => None,
        })
        .unwrap()
}

#[test]
fn a_point_budget_below_the_root_node_draws_the_root_with_one_warning() {
    let path = gpu::dragon();
    let root = root_points(&path);
    assert!(root > 1_000, "{root}");
    let render = |budget: u64, out: &str| {
        let out = scratch(out);
        let o = std::process::Command::new(env!("CARGO_BIN_EXE_surfel"))
            .arg("render")
            .arg(&path)
            .args(["--stream", "--size", "128x128", "--point-budget"])
            .arg(budget.to_string())
            .arg("--out")
            .arg(&out)
            .env("XDG_RUNTIME_DIR", std::env::temp_dir())
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&o.stderr).into_owned();
        assert!(o.status.success(), "{stderr}");
        (image::open(&out).unwrap().to_rgba8(), stderr)
    };
    let (tiny, warned) = render(1, "budget-1.png");
    let (whole_root, quiet) = render(root, "budget-root.png");
    let warning = format!(
        "warning: the point budget 1 is below the root node's {root} points; drawing the root"
    );
    assert_eq!(
        warned
            .lines()
            .filter(|l| l.starts_with("warning"))
            .collect::<Vec<_>>(),
        [warning.as_str()],
        "{warned}"
    );
    assert!(!quiet.contains("warning"), "{quiet}");
    let drawn = format!("{root} of {root} selected points drawn from 1 nodes");
    assert!(
        warned.contains(&drawn) && quiet.contains(&drawn),
        "{warned}\n{quiet}"
    );
    // The root's points, exactly as a budget of the root's size draws them.
    let covered = |img: &image::RgbaImage| img.pixels().filter(|p| p.0[..3] != [0, 0, 0]).count();
    assert!(covered(&tiny) > 500, "{}", covered(&tiny));
    assert_eq!(covered(&tiny), covered(&whole_root));
    assert!(tiny == whole_root);
}

#[test]
fn the_streamed_legend_lists_the_classes_of_every_node_loaded_with_their_points() {
    use surfel::gpu_scene::streamed::StreamedScene;

    // A survey whose class 65 is two points: the root's subsample lacks it.
    let mut cloud = survey(40_000);
    let classes = &mut cloud
        .scalars
        .iter_mut()
        .find(|s| s.name == "classification")
        .unwrap()
        .values;
    classes[7] = 65.0;
    classes[39_998] = 65.0;
    let path = scratch("legend.copc.laz");
    convert::write_with(&cloud, &path, 2_000).unwrap();
    let ctx = common::context();
    let mut s = StreamedScene::open(
        &ctx,
        path.to_str().unwrap(),
        &gpu::options(u64::MAX, 64 << 20, 0.0),
        |root| Ok(surfel::color::select(root, "classification", surfel::scene::Up::Z).unwrap()),
        2,
    )
    .unwrap();
    let has =
        |legend: &[surfel::color::LegendEntry], class: u32| legend.iter().any(|e| e.class == class);
    // At open: the root's classes.
    assert_eq!(s.legend(), surfel::color::legend(&s.root));
    assert!(!has(&s.legend(), 65), "the root holds class 65");
    let (centre, radius) = s.bounding_sphere();
    let camera = gpu::framing(centre, radius);
    for round in 0.. {
        assert!(round < 2000, "streaming never settled");
        s.update(&camera, 128, 128).unwrap();
        if s.stable() {
            break;
        }
        s.wait(std::time::Duration::from_millis(50));
    }
    // Every node loaded: the file's classes with their exact counts, class 65 included.
    assert_eq!(s.stats().drawn_points, 40_000);
    let whole = surfel::color::legend(&scene::load(&path).unwrap());
    assert_eq!(s.legend(), whole);
    assert_eq!(s.legend_classes(), 13);
    let rare = s.legend().into_iter().find(|e| e.class == 65).unwrap();
    assert_eq!(rare.count, 2);
    common::assert_clean(&ctx);
}

#[test]
fn http_and_local_file_stream_the_same_image() {
    let path = gpu::dragon();
    let options = gpu::options(PART, 64 << 20, 1.0);
    let local = gpu::stream(path.to_str().unwrap(), &options, &[&gpu::framing], 192);
    let server = http::serve(std::fs::read(&path).unwrap(), Box::new(|_, _| None));
    let remote = gpu::stream(&server.url, &options, &[&gpu::framing], 192);
    assert!(local.messages.is_empty() && remote.messages.is_empty());
    assert_eq!(local.stats.selected_points, remote.stats.selected_points);
    assert_eq!(local.stats.drawn_points, remote.stats.drawn_points);
    assert!(
        local.stats.drawn_points <= PART && local.stats.drawn_points > 30_000,
        "{:?}",
        local.stats
    );
    assert!(*server.requests.lock().unwrap() as usize >= local.stats.selected_nodes);
    // The same points; where two share a pixel at the same depth, the draw order (which slot
    // a node landed in) may pick either.
    let differ = gpu::coverage_difference(&local.frame, &remote.frame);
    assert_eq!(differ, 0.0);
    let colors = (0..local.frame.pixels())
        .filter(|&i| local.frame.color[i] != remote.frame.color[i])
        .count();
    assert!(
        colors * 1000 < local.frame.pixels(),
        "{colors} pixels differ"
    );
}

#[test]
fn server_errors_are_retried_and_bad_urls_are_clear_errors() {
    let path = gpu::dragon();
    let options = gpu::options(PART, 64 << 20, 1.0);
    let clean = gpu::stream(path.to_str().unwrap(), &options, &[&gpu::framing], 128);
    // Every range fails twice with a 500 or 503 before it is served.
    let flaky = http::serve(
        std::fs::read(&path).unwrap(),
        Box::new(|at, attempt| match attempt {
            0 => Some(500),
            1 if at % 2 == 0 => Some(503),
            _ => None,
        }),
    );
    let retried = gpu::stream(&flaky.url, &options, &[&gpu::framing], 128);
    assert!(retried.messages.is_empty(), "{:?}", retried.messages);
    assert_eq!(retried.stats.drawn_points, clean.stats.drawn_points);
    assert_eq!(gpu::coverage_difference(&retried.frame, &clean.frame), 0.0);
    // A missing file, a server that never succeeds and a file that is not COPC.
    let open = |url: &str| {
        surfel::copc::loader::Loader::open(url, options.loader.clone())
            .err()
            .expect("an error")
            .to_string()
    };
    let server = http::serve(std::fs::read(&path).unwrap(), Box::new(|_, _| None));
    let missing = server.url.replace("cloud.copc.laz", "other.copc.laz");
    let m = open(&missing);
    assert!(m.contains(&missing) && m.contains("HTTP 404"), "{m}");
    let down = http::serve(Vec::new(), Box::new(|_, _| Some(500)));
    let m = open(&down.url);
    assert!(m.contains("HTTP 500 (after 4 attempts)"), "{m}");
    let ply = std::fs::read("../shared/data/stanford/bun_zipper.ply").unwrap();
    let not_copc = http::serve(ply, Box::new(|_, _| None));
    let m = open(&not_copc.url);
    assert!(m.contains(&not_copc.url) && m.contains("LAS"), "{m}");
}

#[test]
fn a_corrupt_node_is_skipped_with_one_message() {
    let path = gpu::dragon();
    let mut bytes = std::fs::read(&path).unwrap();
    // Find a level-1 node and garble its chunk.
    let source = FileSource::open(&path).unwrap();
    let copc = CopcFile::open(&source).unwrap();
    let (at, len) = copc.info.root;
    let node = scene::copc::read_page(&copc.file, &source, at, len, copc.size)
        .unwrap()
        .into_iter()
        .find_map(|e| match e {
            Entry::Node(n) if n.key.level == 1 => Some(n),
            _ => None,
        })
        .unwrap();
    // The first layer's size (after the 30-byte first point and the point count) claims more
    // than the chunk holds.
    let sizes = node.offset as usize + 34;
    bytes[sizes..sizes + 4].copy_from_slice(&0x7fff_ffffu32.to_le_bytes());
    let corrupt = scratch("corrupt.copc.laz");
    std::fs::write(&corrupt, &bytes).unwrap();
    let options = gpu::options(u64::MAX, 64 << 20, 1.0);
    let clean = gpu::stream(path.to_str().unwrap(), &options, &[&gpu::framing], 128);
    let damaged = gpu::stream(corrupt.to_str().unwrap(), &options, &[&gpu::framing], 128);
    assert_eq!(damaged.messages.len(), 1, "{:?}", damaged.messages);
    let m = &damaged.messages[0];
    assert!(
        m.contains(&format!("node {}", node.key)) && m.contains(&format!("byte {}", node.offset)),
        "{m}"
    );
    assert_eq!(damaged.stats.failed, 1);
    // The rest is drawn: the image keeps most of its pixels.
    let kept = common::coverage(&damaged.frame) / common::coverage(&clean.frame);
    assert!(kept > 0.7 && kept <= 1.0, "{kept}");
}

#[test]
fn eviction_under_a_small_memory_budget_keeps_the_image_complete() {
    let path = gpu::dragon();
    let location = path.to_str().unwrap();
    // Room for 16 batches (one per node here): two close views from opposite sides need more
    // between them, so the second evicts the first's nodes.
    let small = gpu::options(100_000, 16 * 30 * 10240, 0.5);
    let large = gpu::options(100_000, 512 << 20, 0.5);
    let side = |sign: f32| {
        move |c: Vec3, r: f32| {
            let mut camera = gpu::framing(c, r);
            camera.eye = camera.target + (camera.eye - camera.target) * 0.3 * sign;
            camera
        }
    };
    let (front, back) = (side(1.0), side(-1.0));
    let reference = gpu::stream(location, &large, &[&gpu::framing], 256);
    let evicting = gpu::stream(location, &small, &[&front, &back, &gpu::framing], 256);
    assert!(evicting.stats.evicted > 0, "{:?}", evicting.stats);
    assert!(evicting.stats.used_slots <= evicting.stats.slots);
    // Back at the first view, every node it chooses is resident again.
    assert_eq!(
        evicting.stats.drawn_points, reference.stats.drawn_points,
        "{:?} vs {:?}",
        evicting.stats, reference.stats
    );
    assert_eq!(
        gpu::coverage_difference(&evicting.frame, &reference.frame),
        0.0
    );
}

/// Every method either draws a streamed LiDAR file (colour by intensity, eye-dome lighting on)
/// or refuses it for reading the whole cloud.
#[test]
fn every_method_draws_a_streamed_cloud_or_says_it_needs_the_whole_cloud() {
    use surfel::gpu_scene::streamed::StreamedScene;
    use surfel::methods::{MethodConfig, METHODS};
    use surfel::post::{Edl, PostOptions};
    use surfel::render::{Renderer, RendererOptions, View};

    let lidar = scene::load(Path::new("../shared/data/lidar/autzen_trim.laz")).unwrap();
    let path = scratch("autzen.copc.laz");
    convert::write_with(&lidar, &path, 8_000).unwrap();
    let ctx = common::context();
    // A fine screen-space error, so the small image still needs several levels.
    let mut options = gpu::options(60_000, 64 << 20, 0.1);
    options.loader.k = 8;
    options.loader.normal_field = true;
    let mut s = StreamedScene::open(
        &ctx,
        path.to_str().unwrap(),
        &options,
        |root| Ok(surfel::color::select(root, "intensity", surfel::scene::Up::Z).unwrap()),
        2,
    )
    .unwrap();
    assert!(s.info.has_colors && s.info.has_normals);
    let (centre, radius) = s.bounding_sphere();
    let camera = surfel::scene::Up::Z.default_pose().camera(
        centre,
        radius,
        surfel::scene::Up::Z,
        s.origin(),
    );
    for _ in 0..2000 {
        s.update(&camera, 96, 96).unwrap();
        if s.stable() {
            break;
        }
        s.wait(std::time::Duration::from_millis(50));
    }
    assert!(
        s.stable() && s.stats().drawn_points > 20_000,
        "{:?}",
        s.stats()
    );
    let mut drawn = Vec::new();
    for m in METHODS {
        let config = MethodConfig::parse(m.name).unwrap();
        let extras = RendererOptions {
            readback: true,
            frames_in_flight: 2,
            post: PostOptions {
                edl: Some(Edl::default()),
                ..PostOptions::NONE
            },
            ..RendererOptions::default()
        };
        let whole = m.needs_lod || m.needs_hpr || m.needs_faces;
        match Renderer::new(&ctx, &s.scene, s.info, &config, 96, 96, extras) {
            Err(e) => {
                assert!(whole, "{}: {e}", m.name);
                assert!(e.to_string().contains("reads the whole cloud"), "{e}");
            }
            Ok(mut r) => {
                assert!(!whole, "{} should refuse a streamed scene", m.name);
                let view = View {
                    camera,
                    lights: Vec::new(),
                    use_color: true,
                    time: 0.0,
                };
                let frame = r
                    .render_batches(&view, Some(s.batches()), true)
                    .unwrap()
                    .unwrap();
                let covered = common::coverage(&frame);
                assert!(covered > 0.1, "{}: {covered}", m.name);
                assert!(frame.depth.iter().all(|d| !d.is_nan()), "{}", m.name);
                drawn.push(m.name);
            }
        }
    }
    common::assert_clean(&ctx);
    for family in [
        "points",
        "compute",
        "perspective-phong",
        "ewa",
        "pyramid",
        "kernel",
    ] {
        assert!(
            drawn.iter().any(|n| n.starts_with(family)),
            "{family}: {drawn:?}"
        );
    }
}

#[test]
fn a_binary_ply_is_converted_with_compact_normals_and_radii() {
    let mut cloud = survey(30_000);
    // PLY keeps positions, normals, colours and radii (not the LAS fields).
    cloud.scalars.clear();
    let dir = scratch("ply-stream");
    std::fs::create_dir_all(&dir).unwrap();
    let ply = dir.join("survey.ply");
    scene::ply::save(&ply, &cloud).unwrap();
    let out = dir.join("survey.copc.laz");
    let stats = convert::convert(
        &ply,
        &out,
        &convert::ConvertOptions {
            node_points: 2_000,
            ..convert::ConvertOptions::default()
        },
    )
    .unwrap();
    assert_eq!(stats.points, 30_000);
    // The output has the mode of a new file: 0666 less the umask.
    // SAFETY: swaps the file-creation mask and puts it back at once.
    let umask = unsafe {
        let mask = libc::umask(0o022);
        libc::umask(mask);
        mask
    };
    use std::os::unix::fs::PermissionsExt;
    let mode = std::fs::metadata(&out).unwrap().permissions().mode() & 0o777;
    assert_eq!(mode, 0o666 & !umask);
    let leftovers: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with('.'))
        .collect();
    assert!(leftovers.is_empty(), "{leftovers:?}");
    let back = scene::load(&out).unwrap();
    let (a, b) = (by_position(&cloud), by_position(&back));
    assert_eq!(a.len(), b.len());
    for ((ka, za, ia), (kb, zb, ib)) in a.iter().zip(&b) {
        assert_eq!(ka, kb);
        assert!((za - zb).abs() < 2e-5);
        assert_eq!(
            cloud.colors.as_ref().unwrap()[*ia],
            back.colors.as_ref().unwrap()[*ib]
        );
        let (ra, rb) = (
            cloud.radii.as_ref().unwrap()[*ia],
            back.radii.as_ref().unwrap()[*ib],
        );
        assert!((ra - rb).abs() <= 0.005 * ra, "radius {ra} vs {rb}");
    }
    // The root node is a uniform sample: its points span the cloud, not the first rows.
    let source = FileSource::open(&out).unwrap();
    let copc = CopcFile::open(&source).unwrap();
    let (at, len) = copc.info.root;
    let root = scene::copc::read_page(&copc.file, &source, at, len, copc.size)
        .unwrap()
        .into_iter()
        .find_map(|e| match e {
            Entry::Node(n) if n.key == Key::ROOT => Some(n),
            _ => None,
        })
        .unwrap();
    let ys: Vec<f64> = copc
        .read_node(&source, &root)
        .unwrap()
        .world
        .iter()
        .map(|p| p.y)
        .collect();
    let (lo, hi) = ys
        .iter()
        .fold((f64::MAX, f64::MIN), |(l, h), &y| (l.min(y), h.max(y)));
    let (clo, chi) = cloud.bounds().unwrap();
    let span = f64::from(chi.y - clo.y);
    assert!(hi - lo > 0.95 * span, "root spans {} of {span}", hi - lo);
}

#[test]
fn las_and_laz_are_converted_in_blocks_with_every_field() {
    let dir = scratch("las-stream");
    std::fs::create_dir_all(&dir).unwrap();
    for name in ["autzen_trim.las", "autzen_trim.laz"] {
        let input = Path::new("../shared/data/lidar").join(name);
        let out = dir.join(format!("{name}.copc.laz"));
        convert::convert(&input, &out, &convert::ConvertOptions::default()).unwrap();
        let (a, b) = (scene::load(&input).unwrap(), scene::load(&out).unwrap());
        assert_eq!(a.len(), b.len());
        // GPS times count from the same earliest time, in the LAS file and in its COPC.
        assert_eq!(a.stats.gps_time_origin, b.stats.gps_time_origin, "{name}");
        assert_eq!(
            surfel::color::min_max(scalar(&a, "gps_time")).0,
            0.0,
            "{name}"
        );
        let key = |c: &Cloud, i: usize| {
            let w = c.origin + c.positions[i].as_dvec3();
            [w.x, w.y, w.z].map(|v| (v * 100.0).round() as i64)
        };
        let sorted = |c: &Cloud| {
            let mut idx: Vec<usize> = (0..c.len()).collect();
            idx.sort_by_key(|&i| (key(c, i), scalar(c, "gps_time")[i].to_bits()));
            idx
        };
        for (&i, &j) in sorted(&a).iter().zip(&sorted(&b)) {
            assert_eq!(key(&a, i), key(&b, j), "{name}");
            assert_eq!(a.colors.as_ref().unwrap()[i], b.colors.as_ref().unwrap()[j]);
            for field in [
                "intensity",
                "classification",
                "return_number",
                "point_source_id",
                "gps_time",
            ] {
                assert_eq!(scalar(&a, field)[i], scalar(&b, field)[j], "{name} {field}");
            }
        }
    }
    // A truncated LAZ is an error naming the file, and leaves no temporary files behind.
    let mut bytes = std::fs::read("../shared/data/lidar/autzen_trim.laz").unwrap();
    bytes.truncate(bytes.len() / 2);
    let cut = dir.join("cut.laz");
    std::fs::write(&cut, &bytes).unwrap();
    let m = convert::convert(
        &cut,
        &dir.join("cut.copc.laz"),
        &convert::ConvertOptions::default(),
    )
    .unwrap_err()
    .to_string();
    assert!(m.contains("cut.laz"), "{m}");
    let leftovers: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with('.'))
        .collect();
    assert!(leftovers.is_empty(), "{leftovers:?}");
}

#[test]
fn e57_is_converted_point_by_point() {
    let dir = scratch("e57-stream");
    std::fs::create_dir_all(&dir).unwrap();
    let input = Path::new("../shared/data/e57/tinyCartesianFloatRgb.e57");
    let out = dir.join("tiny.copc.laz");
    convert::convert(input, &out, &convert::ConvertOptions::default()).unwrap();
    let (a, b) = (scene::load(input).unwrap(), scene::load(&out).unwrap());
    assert_eq!(a.len(), b.len());
    let key = |c: &Cloud, i: usize| {
        let w = c.origin + c.positions[i].as_dvec3();
        [w.x, w.y, w.z].map(|v| (v * 1e4).round() as i64)
    };
    let sorted = |c: &Cloud| {
        let mut k: Vec<_> = (0..c.len())
            .map(|i| (key(c, i), c.colors.as_ref().unwrap()[i]))
            .collect();
        k.sort();
        k
    };
    assert_eq!(sorted(&a), sorted(&b));
    let m = convert::convert(
        Path::new("../shared/data/e57/corrupt_crc.e57"),
        &dir.join("bad.copc.laz"),
        &convert::ConvertOptions::default(),
    )
    .unwrap_err()
    .to_string();
    assert!(
        m.contains("corrupt_crc.e57") && m.contains("checksum"),
        "{m}"
    );
    let leftovers: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with('.'))
        .collect();
    assert!(leftovers.is_empty(), "{leftovers:?}");
}

#[test]
fn a_server_that_stops_answering_is_timed_out_and_retried() {
    let path = gpu::dragon();
    // Every range's first request gets no answer within the client's 300 ms.
    let slow = http::serve(
        std::fs::read(&path).unwrap(),
        Box::new(|_, attempt| (attempt == 0).then_some(0)),
    );
    let mut options = gpu::options(PART, 64 << 20, 1.0);
    options.loader.http.timeout = std::time::Duration::from_millis(300);
    let start = std::time::Instant::now();
    let opened = surfel::copc::loader::Loader::open(&slow.url, options.loader.clone()).unwrap();
    assert!(start.elapsed() >= std::time::Duration::from_millis(300));
    assert_eq!(opened.root.len(), 8_000);
    // Streamed through the same server, every node arrives after its retry.
    let streamed = gpu::stream(&slow.url, &options, &[&gpu::framing], 128);
    assert!(streamed.messages.is_empty(), "{:?}", streamed.messages);
    assert!(streamed.stats.drawn_points > 30_000);
}

#[test]
fn a_stopped_conversion_leaves_no_files() {
    static STOPPED: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(true);
    let dir = scratch("stopped");
    std::fs::create_dir_all(&dir).unwrap();
    let ply = dir.join("survey.ply");
    scene::ply::save(&ply, &survey(5_000)).unwrap();
    let out = dir.join("survey.copc.laz");
    for input in [
        ply.clone(),
        PathBuf::from("../shared/data/lidar/autzen_trim.laz"),
    ] {
        let options = convert::ConvertOptions {
            stop: Some(&STOPPED),
            ..convert::ConvertOptions::default()
        };
        let m = convert::convert(&input, &out, &options).unwrap_err();
        assert_eq!(
            m.to_string(),
            format!(
                "{}: interrupted; the temporary files are removed and no output is written",
                out.display()
            )
        );
        let files: Vec<_> = std::fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        assert_eq!(files, ["survey.ply"], "{}", input.display());
    }
}

/// A forest of 5 x 5 octrees seen at a grazing angle from one corner, one tree not opened:
/// the near trees alone could spend a small budget, yet every tree in view has its root drawn
/// (or is to be opened) whatever the budget, and the rest of the budget goes below the roots.
#[test]
fn every_tree_in_view_has_its_root_drawn_whatever_the_budget() {
    let (h, base) = octree(4);
    let infos: Vec<Info> = (0..25)
        .map(|k| Info {
            center: DVec3::new(16.0 * (k % 5) as f64, 16.0 * (k / 5) as f64, 0.0),
            ..base
        })
        .collect();
    let trees: Vec<Tree> = infos
        .iter()
        .enumerate()
        .map(|(k, info)| Tree {
            hierarchy: (k != 18).then_some(&h),
            info,
            bounds: info.cube(Key::ROOT),
        })
        .collect();
    let v = view(
        Vec3::new(-12.0, -12.0, 6.0),
        Vec3::new(64.0, 64.0, 0.0),
        0.5,
    );
    let roots = |points: u64| {
        let s = select_forest(
            &trees,
            DVec3::ZERO,
            &v,
            Budget {
                points,
                slots: u64::MAX,
            },
        );
        let mut r: Vec<usize> = s
            .nodes
            .iter()
            .filter(|(_, k)| *k == Key::ROOT)
            .map(|(t, _)| *t)
            .collect();
        r.sort();
        (s, r)
    };
    let (all, all_roots) = roots(u64::MAX);
    assert!(all_roots.len() >= 10, "{all_roots:?}");
    assert_eq!(all.open, [18]);
    let root_points: u64 = all_roots.len() as u64 * h.nodes[&Key::ROOT].points;
    for points in [1, root_points, root_points + 200_000] {
        let (s, r) = roots(points);
        assert_eq!(r, all_roots, "budget {points}");
        assert_eq!(s.open, [18]);
        assert!(
            s.points <= points.max(root_points),
            "budget {points}: {}",
            s.points
        );
        let chosen: std::collections::HashSet<_> = s.nodes.iter().collect();
        for (t, k) in &s.nodes {
            assert!(*k == Key::ROOT || chosen.contains(&(*t, k.parent())));
        }
        if points > root_points {
            assert!(
                s.points > root_points,
                "the budget left goes below the roots"
            );
        }
    }
}
