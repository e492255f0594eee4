//! Virtual point clouds (`.vpc`): the writer's output against the spec, and streaming a
//! forest of tiles from files and over HTTP.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use glam::{DVec3, Vec3};
use serde_json::Value;
use surfel::color;
use surfel::copc::loader::LoaderOptions;
use surfel::copc::{convert, vpc};
use surfel::frame::Frame;
use surfel::gpu_scene::streamed::{StreamOptions, StreamStats, StreamedScene};
use surfel::methods::MethodConfig;
use surfel::render::{Renderer, RendererOptions, View};
use surfel::scene::{Camera, Cloud, Scalar, Up};
use surfel::source::HttpOptions;

use crate::common;

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir()
        .join(format!("surfel-vpc-{}", std::process::id()))
        .join(name);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Edge of a tile in metres.
const TILE: f64 = 40.0;

/// The points of tile `(ix, iy)`: a wavy sheet at UTM-sized coordinates on a 0.5 m grid, with
/// colours, intensity and classification.
fn tile_cloud(ix: usize, iy: usize) -> Cloud {
    let side = (TILE / 0.5) as usize;
    let origin = DVec3::new(
        500_000.0 + ix as f64 * TILE,
        4_000_000.0 + iy as f64 * TILE,
        100.0,
    );
    let mut positions = Vec::new();
    for j in 0..side {
        for i in 0..side {
            let (x, y) = (i as f32 * 0.5 + 0.25, j as f32 * 0.5 + 0.25);
            let (wx, wy) = (x + (ix as f64 * TILE) as f32, y + (iy as f64 * TILE) as f32);
            positions.push(Vec3::new(
                x,
                y,
                (wx * 0.05).sin() * 3.0 + (wy * 0.04).cos() * 2.0,
            ));
        }
    }
    let n = positions.len();
    Cloud {
        colors: Some(
            (0..n)
                .map(|i| {
                    [
                        (i % 200) as u8 + 40,
                        (ix * 60 % 256) as u8,
                        (iy * 60 % 256) as u8,
                        255,
                    ]
                })
                .collect(),
        ),
        scalars: vec![
            Scalar {
                name: "intensity".into(),
                values: (0..n).map(|i| (i * 37 % 4000) as f32).collect(),
            },
            Scalar {
                name: "classification".into(),
                values: (0..n).map(|i| (2 + i % 3) as f32).collect(),
            },
        ],
        positions,
        origin,
        up: Up::Z,
        ..Cloud::default()
    }
}

/// A `side` x `side` grid of COPC tiles under `dir/tiles` and its `.vpc` at `dir/grid.vpc`;
/// tile `iy * side + ix` is item `iy * side + ix`.
fn grid(dir: &Path, side: usize) -> PathBuf {
    let tiles = dir.join("tiles");
    std::fs::create_dir_all(&tiles).unwrap();
    let out = dir.join("grid.vpc");
    let summaries: Vec<vpc::TileSummary> = (0..side * side)
        .map(|k| {
            let path = tiles.join(format!("t{k:02}.copc.laz"));
            convert::write_with(&tile_cloud(k % side, k / side), &path, 400).unwrap();
            vpc::summarize(&out, &path).unwrap()
        })
        .collect();
    vpc::write(&out, &summaries).unwrap();
    out
}

fn options(point_budget: u64) -> StreamOptions {
    StreamOptions {
        point_budget,
        gpu_bytes: 64 << 20,
        error_px: 0.0,
        loader: LoaderOptions {
            threads: 2,
            k: 0,
            scalar: None,
            normal_field: false,
            http: HttpOptions {
                attempts: 3,
                backoff: Duration::from_millis(5),
                timeout: Duration::from_secs(10),
                connections: 4,
            },
        },
    }
}

struct Streamed {
    frame: Frame,
    stats: StreamStats,
    messages: Vec<String>,
    /// Per tile: href, opened, bytes read.
    tiles: Vec<(String, bool, u64)>,
}

/// Streams `location` until the view of `camera` (from the framing sphere) is complete.
fn stream(
    location: &str,
    options: &StreamOptions,
    camera: &dyn Fn(&StreamedScene) -> Camera,
    size: u32,
) -> Streamed {
    stream_filtered(location, options, camera, size, None)
}

/// [`stream`] drawn through `filter` (file coordinates).
fn stream_filtered(
    location: &str,
    options: &StreamOptions,
    camera: &dyn Fn(&StreamedScene) -> Camera,
    size: u32,
    filter: Option<&surfel::scene::clip::Filter>,
) -> Streamed {
    let ctx = common::context();
    let mut s = StreamedScene::open(
        &ctx,
        location,
        options,
        |root| Ok(color::select(root, "rgb", Up::Z).unwrap()),
        2,
    )
    .unwrap();
    let mut r = Renderer::new(
        &ctx,
        &s.scene,
        s.info,
        &MethodConfig::parse("points").unwrap(),
        size,
        size,
        RendererOptions {
            readback: true,
            frames_in_flight: 2,
            ..RendererOptions::default()
        },
    )
    .unwrap();
    r.set_filter(filter.and_then(|f| f.active(s.origin())));
    let camera = camera(&s);
    let view = View {
        camera,
        lights: Vec::new(),
        use_color: true,
        time: 0.0,
    };
    let mut messages = Vec::new();
    for round in 0.. {
        assert!(round < 2000, "streaming never settled");
        s.update(&camera, size, size).unwrap();
        assert!(s.stats().selected_points <= options.point_budget);
        r.render_batches(&view, Some(s.batches()), false).unwrap();
        messages.extend(s.take_messages());
        if s.stable() {
            break;
        }
        s.wait(Duration::from_millis(50));
    }
    let frame = r.render_batches(&view, Some(s.batches()), true).unwrap();
    messages.extend(s.take_messages());
    drop(r);
    common::assert_clean(&ctx);
    Streamed {
        frame: frame.unwrap(),
        stats: s.stats(),
        messages,
        tiles: s
            .tiles()
            .iter()
            .map(|t| (t.href.clone(), t.file.is_some(), t.bytes_read()))
            .collect(),
    }
}

fn framing(s: &StreamedScene) -> Camera {
    let (c, r) = s.bounding_sphere();
    Camera::framing(c, r)
}

#[test]
fn the_written_vpc_has_every_field_the_spec_requires() {
    let dir = scratch("fields");
    let path = grid(&dir, 2);
    let json: Value = serde_json::from_slice(&std::fs::read(&path).unwrap()).unwrap();
    assert_eq!(json["type"], "FeatureCollection");
    let features = json["features"].as_array().unwrap();
    assert_eq!(features.len(), 4);
    for (k, f) in features.iter().enumerate() {
        assert_eq!(f["type"], "Feature");
        assert_eq!(f["stac_version"], "1.0.0");
        assert_eq!(
            f["stac_extensions"],
            serde_json::json!([
                "https://stac-extensions.github.io/pointcloud/v1.0.0/schema.json",
                "https://stac-extensions.github.io/projection/v1.1.0/schema.json"
            ])
        );
        assert_eq!(f["id"], format!("t{k:02}"));
        // No CRS: no WGS 84 footprint.
        assert!(f["geometry"].is_null());
        assert!(f.get("bbox").is_none());
        assert_eq!(f["links"], serde_json::json!([]));
        let p = &f["properties"];
        assert!(p["datetime"].as_str().unwrap().ends_with("T00:00:00Z"));
        assert_eq!(p["pc:count"], 6400);
        assert_eq!(p["pc:type"], "lidar");
        assert_eq!(p["pc:encoding"], "application/vnd.laszip+copc");
        let names: Vec<&str> = p["pc:schemas"]
            .as_array()
            .unwrap()
            .iter()
            .map(|d| d["name"].as_str().unwrap())
            .collect();
        assert_eq!(&names[..3], ["X", "Y", "Z"]);
        assert!(names.contains(&"Red") && names.contains(&"Classification"));
        assert!(p.get("proj:epsg").is_some_and(Value::is_null));
        let bbox: Vec<f64> = p["proj:bbox"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_f64().unwrap())
            .collect();
        let (ix, iy) = ((k % 2) as f64, (k / 2) as f64);
        assert_eq!(bbox.len(), 6);
        assert!(
            (bbox[0] - (500_000.25 + ix * TILE)).abs() < 1e-6,
            "{bbox:?}"
        );
        assert!(
            (bbox[4] - (4_000_000.0 + iy * TILE + TILE - 0.25)).abs() < 1e-6,
            "{bbox:?}"
        );
        assert_eq!(p["proj:geometry"]["type"], "Polygon");
        let data = &f["assets"]["data"];
        assert_eq!(data["href"], format!("./tiles/t{k:02}.copc.laz"));
        assert_eq!(data["roles"], serde_json::json!(["data"]));
    }
    let parsed = vpc::read(path.to_str().unwrap(), &HttpOptions::default()).unwrap();
    for (k, t) in parsed.tiles.iter().enumerate() {
        assert_eq!(
            t.location,
            dir.join(format!("tiles/t{k:02}.copc.laz"))
                .display()
                .to_string()
        );
        assert!(Path::new(&t.location).is_file());
    }
    assert_eq!(parsed.points(), 4 * 6400);
}

/// Writes `cloud` as an uncompressed LAS 1.2 file (point format 3: colours, GPS time).
fn write_las(cloud: &Cloud, path: &Path) {
    let mut builder = las::Builder::from((1, 2));
    builder.point_format = las::point::Format::new(3).unwrap();
    builder.transforms = las::Vector {
        x: las::Transform {
            scale: 0.001,
            offset: cloud.origin.x,
        },
        y: las::Transform {
            scale: 0.001,
            offset: cloud.origin.y,
        },
        z: las::Transform {
            scale: 0.001,
            offset: cloud.origin.z,
        },
    };
    let mut w = las::Writer::from_path(path, builder.into_header().unwrap()).unwrap();
    let colors = cloud.colors.as_ref().unwrap();
    for (i, p) in cloud.positions.iter().enumerate() {
        let q = cloud.origin + p.as_dvec3();
        let c = colors[i];
        w.write_point(las::Point {
            x: q.x,
            y: q.y,
            z: q.z,
            intensity: cloud.scalars[0].values[i] as u16,
            classification: las::point::Classification::new(cloud.scalars[1].values[i] as u8)
                .unwrap(),
            color: Some(las::Color::new(
                u16::from(c[0]) * 257,
                u16::from(c[1]) * 257,
                u16::from(c[2]) * 257,
            )),
            gps_time: Some(0.0),
            ..las::Point::default()
        })
        .unwrap();
    }
    w.close().unwrap();
}

#[test]
fn a_hand_written_vpc_with_las_and_copc_tiles_loads() {
    let dir = scratch("mixed");
    std::fs::create_dir_all(dir.join("data")).unwrap();
    convert::write_with(&tile_cloud(0, 0), &dir.join("data/a.copc.laz"), 400).unwrap();
    convert::write_with(&tile_cloud(1, 0), &dir.join("data/b.copc.laz"), 400).unwrap();
    write_las(&tile_cloud(0, 1), &dir.join("data/c.las"));
    let item = |id: &str, href: &str, encoding: &str, ix: f64, iy: f64| {
        let (x, y) = (500_000.0 + ix * TILE, 4_000_000.0 + iy * TILE);
        format!(
            r#"{{
      "type": "Feature",
      "stac_version": "1.0.0",
      "stac_extensions": [
        "https://stac-extensions.github.io/pointcloud/v1.0.0/schema.json",
        "https://stac-extensions.github.io/projection/v1.1.0/schema.json"
      ],
      "id": "{id}",
      "geometry": null,
      "properties": {{
        "datetime": "2023-05-01T00:00:00Z",
        "pc:count": 6400,
        "pc:encoding": "{encoding}",
        "pc:schemas": [],
        "pc:type": "lidar",
        "proj:bbox": [{x}, {y}, 94.0, {}, {}, 106.0],
        "proj:epsg": null
      }},
      "links": [],
      "assets": {{ "data": {{ "href": "{href}", "roles": ["data"] }} }}
    }}"#,
            x + TILE,
            y + TILE
        )
    };
    let text = format!(
        "{{\n  \"type\": \"FeatureCollection\",\n  \"features\": [\n    {},\n    {},\n    {}\n  ]\n}}\n",
        item("a", "./data/a.copc.laz", "application/vnd.laszip+copc", 0.0, 0.0),
        item("b", "data/b.copc.laz", "application/vnd.laszip+copc", 1.0, 0.0),
        item("c", "./data/../data/c.las", "application/vnd.las", 0.0, 1.0),
    );
    let path = dir.join("mixed.vpc");
    std::fs::write(&path, text).unwrap();
    let s = stream(path.to_str().unwrap(), &options(u64::MAX), &framing, 128);
    assert!(s.messages.is_empty(), "{:?}", s.messages);
    assert_eq!(s.stats.tiles, 3);
    assert_eq!(s.stats.tiles_open, 3);
    assert_eq!(s.stats.drawn_points, 3 * 6400);
    assert!(
        common::coverage(&s.frame) > 0.2,
        "{}",
        common::coverage(&s.frame)
    );
}

#[test]
fn tiles_outside_the_view_are_never_read() {
    let dir = scratch("culled");
    let path = grid(&dir, 4);
    // Close above tile 0 (x and y in [0, TILE) of the grid), looking straight down.
    let above_tile_0 = |s: &StreamedScene| {
        let corner = (DVec3::new(500_000.0, 4_000_000.0, 100.0) - s.origin()).as_vec3();
        let centre = corner + Vec3::new(TILE as f32 * 0.5, TILE as f32 * 0.5, 0.0);
        Camera::look_at_up(Up::Z, centre + Vec3::new(0.0, -1.0, 30.0), centre, 1.0)
    };
    let s = stream(
        path.to_str().unwrap(),
        &options(u64::MAX),
        &above_tile_0,
        96,
    );
    assert!(s.messages.is_empty(), "{:?}", s.messages);
    assert!(s.tiles[0].1 && s.tiles[0].2 > 0);
    // The view reaches tiles 0, 1, 4 and 5 at most; one of the four tiles at the grid's
    // centre (5, 6, 9, 10) is opened first, whatever the view.
    let mut central = 0;
    for (k, (href, opened, bytes)) in s.tiles.iter().enumerate() {
        if [6, 9, 10].contains(&k) && *opened {
            central += 1;
        } else if k % 4 >= 2 || k / 4 >= 2 {
            assert!(
                !opened && *bytes == 0,
                "{href}: opened {opened}, {bytes} bytes read"
            );
        }
    }
    assert!(central <= 1, "{central}");
    assert!(s.stats.tiles_open <= 5, "{}", s.stats.tiles_open);
    assert!(
        common::coverage(&s.frame) > 0.1,
        "{}",
        common::coverage(&s.frame)
    );
}

/// A loopback HTTP/1.1 server for the files under a directory, answering `Range` requests on
/// kept-alive connections. `fault(path, attempt)` may replace the `attempt`-th answer (from 0)
/// for a path with a status code.
struct Server {
    url: String,
    requests: Arc<Mutex<HashMap<String, u64>>>,
    /// Connections accepted, and the most requests answered at once.
    connections: Arc<AtomicU64>,
    most_at_once: Arc<AtomicU64>,
}

fn serve(root: PathBuf, fault: fn(&str, u64) -> Option<u16>) -> Server {
    use std::io::{BufRead, BufReader, Write};
    let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let url = format!("http://{}", listener.local_addr().unwrap());
    let requests = Arc::new(Mutex::new(HashMap::<String, u64>::new()));
    let count = requests.clone();
    let connections = Arc::new(AtomicU64::new(0));
    let most_at_once = Arc::new(AtomicU64::new(0));
    let busy = Arc::new(AtomicU64::new(0));
    let (accepted, most) = (connections.clone(), most_at_once.clone());
    std::thread::spawn(move || {
        for stream in listener.incoming() {
            let Ok(mut stream) = stream else { continue };
            accepted.fetch_add(1, Ordering::SeqCst);
            let (root, count, busy, most) =
                (root.clone(), count.clone(), busy.clone(), most.clone());
            std::thread::spawn(move || {
                let mut reader = BufReader::new(stream.try_clone().unwrap());
                loop {
                    let mut line = String::new();
                    if reader.read_line(&mut line).unwrap_or(0) == 0 {
                        return;
                    }
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
                    let attempt = {
                        let mut map = count.lock().unwrap();
                        let n = map.entry(path.clone()).or_default();
                        *n += 1;
                        *n - 1
                    };
                    most.fetch_max(busy.fetch_add(1, Ordering::SeqCst) + 1, Ordering::SeqCst);
                    // Answers take a moment, so requests that can overlap do.
                    std::thread::sleep(Duration::from_millis(2));
                    let reply = |stream: &mut std::net::TcpStream,
                                 status: &str,
                                 headers: String,
                                 body: &[u8]| {
                        let head = format!(
                            "HTTP/1.1 {status}\r\nContent-Length: {}\r\n{headers}\r\n",
                            body.len()
                        );
                        stream.write_all(head.as_bytes()).is_ok() && stream.write_all(body).is_ok()
                    };
                    let ok = if let Some(code) = fault(&path, attempt) {
                        reply(&mut stream, &format!("{code} Injected"), String::new(), b"")
                    } else {
                        match std::fs::read(root.join(path.trim_start_matches('/'))) {
                            Err(_) => reply(&mut stream, "404 Not Found", String::new(), b"no"),
                            Ok(bytes) => match range {
                                None => reply(&mut stream, "200 OK", String::new(), &bytes),
                                Some((a, b)) => {
                                    let end = (b as usize).min(bytes.len() - 1);
                                    reply(
                                        &mut stream,
                                        "206 Partial Content",
                                        format!(
                                            "Content-Range: bytes {a}-{end}/{}\r\n",
                                            bytes.len()
                                        ),
                                        &bytes[a as usize..=end],
                                    )
                                }
                            },
                        }
                    };
                    busy.fetch_sub(1, Ordering::SeqCst);
                    if !ok {
                        return;
                    }
                }
            });
        }
    });
    Server {
        url,
        requests,
        connections,
        most_at_once,
    }
}

#[test]
fn sixteen_tiles_over_http_equal_the_local_render() {
    let dir = scratch("http");
    let path = grid(&dir, 4);
    let local = stream(path.to_str().unwrap(), &options(200_000), &framing, 128);
    let server = serve(dir.clone(), |_, _| None);
    let url = format!("{}/grid.vpc", server.url);
    let remote = stream(&url, &options(200_000), &framing, 128);
    assert!(local.messages.is_empty(), "{:?}", local.messages);
    assert!(remote.messages.is_empty(), "{:?}", remote.messages);
    assert_eq!(local.stats.tiles_open, 16);
    assert_eq!(remote.stats.drawn_points, local.stats.drawn_points);
    // Opening a file over HTTP asks for its first byte (its length and range support).
    assert_eq!(remote.stats.bytes_read, local.stats.bytes_read + 16);
    assert!(remote.frame.color == local.frame.color);
    assert!(common::coverage(&local.frame) > 0.3);
    let requests = server.requests.lock().unwrap();
    assert_eq!(requests.len(), 17, "{requests:?}");
    // Connections are kept alive and shared by the tiles: the .vpc's, and at most one per
    // request in flight (4) for the tiles.
    let total: u64 = requests.values().sum();
    let connections = server.connections.load(Ordering::SeqCst);
    assert!(
        connections <= 5,
        "{connections} connections for {total} requests"
    );
    assert!(server.most_at_once.load(Ordering::SeqCst) <= 4);
}

#[test]
fn a_missing_tile_and_a_failing_server_are_each_reported_once() {
    let dir = scratch("faults");
    grid(&dir, 2);
    std::fs::remove_file(dir.join("tiles/t01.copc.laz")).unwrap();
    let server = serve(dir.clone(), |p, _| {
        (p == "/tiles/t02.copc.laz").then_some(503)
    });
    let url = format!("{}/grid.vpc", server.url);
    let s = stream(&url, &options(u64::MAX), &framing, 96);
    let base = format!("{}/tiles", server.url);
    let mut messages = s.messages.clone();
    messages.sort();
    assert_eq!(
        messages,
        [
            format!("tile ./tiles/t01.copc.laz skipped: {base}/t01.copc.laz: bytes 0..1: HTTP 404"),
            format!("tile ./tiles/t02.copc.laz skipped: {base}/t02.copc.laz: bytes 0..1: HTTP 503 (after 3 attempts)"),
        ]
    );
    assert_eq!(s.stats.drawn_points, 2 * 6400);
    assert_eq!(s.stats.tiles_open, 2);
    assert_eq!(server.requests.lock().unwrap()["/tiles/t02.copc.laz"], 3);
}

/// Four LAS tiles (point format 3, each with its own offset) converted into one COPC file and
/// into four tiles with a `.vpc` render the same image at full budget.
#[test]
fn merged_and_tiled_conversions_render_the_same_image() {
    let dir = scratch("merged-and-tiled");
    let input = dir.join("in");
    std::fs::create_dir_all(&input).unwrap();
    for k in 0..4 {
        write_las(&tile_cloud(k % 2, k / 2), &input.join(format!("t{k}.las")));
    }
    let run = |args: &[&str]| {
        let o = std::process::Command::new(env!("CARGO_BIN_EXE_surfel"))
            .args(args)
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    };
    let input = input.to_str().unwrap();
    let merged = dir.join("all.copc.laz");
    let tiled = dir.join("tiled");
    run(&[
        "convert",
        input,
        "--node-points",
        "1000",
        "--out",
        merged.to_str().unwrap(),
    ]);
    run(&[
        "convert",
        input,
        "--tiles",
        "--node-points",
        "1000",
        "--out",
        tiled.to_str().unwrap(),
    ]);
    let all = options(1 << 30);
    let one = stream(merged.to_str().unwrap(), &all, &framing, 160);
    let four = stream(
        tiled.join("tiled.vpc").to_str().unwrap(),
        &all,
        &framing,
        160,
    );
    assert_eq!(one.stats.drawn_points, 4 * 80 * 80);
    assert_eq!(four.stats.drawn_points, one.stats.drawn_points);
    assert!(common::coverage(&one.frame) > 0.3);
    // The merged file and the tiles place the same points in different local frames (the
    // merged header's offset against each tile's), so a point lying on a pixel boundary may
    // round to either side: at most a few pixels per edge row differ.
    let differing = one
        .frame
        .color
        .iter()
        .zip(&four.frame.color)
        .filter(|(a, b)| a != b)
        .count();
    assert!(
        differing <= 80,
        "{differing} of {} pixels differ",
        one.frame.color.len()
    );
}

/// The viewer measures across tiles: each pick reads the drawn nodes under the cursor again
/// and finds a point of its tile, and the distance is between those points.
#[test]
fn the_viewer_measures_a_distance_between_points_of_two_tiles() {
    let dir = scratch("measure");
    let vpc = grid(&dir, 2);
    std::fs::write(dir.join("tour.txt"), "measure distance 60 120 260 120\n").unwrap();
    let o = crate::viewer::view(
        &dir,
        "640x480",
        &vpc,
        &["--size", "320x240", "--stream", "--script", "tour.txt"],
    );
    let stdout = crate::viewer::text(&o.stdout);
    assert!(o.status.success(), "{}", crate::viewer::text(&o.stderr));
    let measure = stdout
        .lines()
        .filter_map(|l| serde_json::from_str::<Value>(l).ok())
        .find_map(|v| v.get("measure").cloned())
        .unwrap_or_else(|| panic!("no measurement: {stdout}"));
    let clouds: Vec<Cloud> = (0..4).map(|k| tile_cloud(k % 2, k / 2)).collect();
    let mut ends = Vec::new();
    let mut tiles = Vec::new();
    for pick in measure["picks"].as_array().unwrap() {
        let p = &pick["point"];
        let at = DVec3::from_slice(
            &(0..3)
                .map(|k| p["position"][k].as_f64().unwrap())
                .collect::<Vec<_>>(),
        );
        let node = p["node"].as_str().unwrap_or_else(|| panic!("{measure}"));
        let k: usize = node[node.find("t0").unwrap() + 2..][..1].parse().unwrap();
        let cloud = &clouds[k];
        let nearest = cloud
            .positions
            .iter()
            .map(|q| (cloud.origin + q.as_dvec3() - at).length())
            .fold(f64::INFINITY, f64::min);
        assert!(
            nearest < 0.01,
            "{pick}: {nearest} m from a point of tile {k}"
        );
        ends.push(at);
        tiles.push(k);
    }
    assert_eq!(ends.len(), 2, "{measure}");
    assert_ne!(tiles[0], tiles[1], "{measure}");
    let distance = measure["distance"].as_f64().unwrap();
    assert!(
        (distance - ends[0].distance(ends[1])).abs() < 1e-6,
        "{measure}"
    );
}

/// A root of 100 points at `centre` (half size 1) with eight children of 100 points.
fn two_levels(centre: DVec3) -> (surfel::copc::select::Hierarchy, surfel::scene::copc::Info) {
    use surfel::scene::copc::{Entry, Info, Key, Node};
    let node = |key| {
        Entry::Node(Node {
            key,
            offset: 0,
            bytes: 1,
            points: 100,
            entry_at: 0,
        })
    };
    let mut h = surfel::copc::select::Hierarchy::default();
    let mut entries = vec![node(Key::ROOT)];
    entries.extend(Key::ROOT.children().map(node));
    h.add_page(0, entries);
    let info = Info {
        center: centre,
        halfsize: 1.0,
        spacing: 0.5,
        root: (0, 0),
        gps_time: (0.0, 0.0),
    };
    (h, info)
}

#[test]
fn every_visible_tile_root_is_drawn_before_any_tile_is_refined() {
    use surfel::copc::select::{select_forest, Budget, SelectView, Tree};
    use surfel::scene::copc::Key;
    let (near, near_info) = two_levels(DVec3::ZERO);
    let (far, far_info) = two_levels(DVec3::new(8.0, 0.0, 0.0));
    let camera = Camera::look_at_up(
        Up::Z,
        Vec3::new(-3.0, 0.0, 2.0),
        Vec3::new(4.0, 0.0, 0.0),
        1.0,
    );
    let view = SelectView {
        view_proj: camera.projection(1.0) * camera.view(),
        eye: camera.eye,
        pixels_per_radian: 500.0,
        error_px: 0.5,
    };
    let unit = (DVec3::splat(-1.0), DVec3::splat(1.0));
    let unopened = |x: f64| Tree {
        hierarchy: None,
        info: &near_info,
        bounds: (
            DVec3::new(x - 1.0, -1.0, -1.0),
            DVec3::new(x + 1.0, 1.0, 1.0),
        ),
    };
    let trees = [
        Tree {
            hierarchy: Some(&near),
            info: &near_info,
            bounds: unit,
        },
        Tree {
            hierarchy: Some(&far),
            info: &far_info,
            bounds: unit,
        },
        // Behind the eye, and ahead.
        unopened(-29.0),
        unopened(16.0),
    ];
    let budget = Budget {
        points: 250,
        slots: 1000,
    };
    let s = select_forest(&trees, DVec3::ZERO, &view, budget);
    // The near tree's children outweigh the far root, yet the far root comes first; the next
    // child exceeds the budget; the tree behind the eye is not opened, the one ahead is.
    assert_eq!(s.nodes, [(0, Key::ROOT), (1, Key::ROOT)]);
    assert_eq!(s.points, 200);
    assert_eq!(s.open, [3]);
}

fn surfel(args: &[&str]) -> std::process::Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_surfel"))
        .args(args)
        .env("XDG_RUNTIME_DIR", std::env::temp_dir())
        .output()
        .expect("run surfel")
}

#[test]
fn info_lists_the_tiles_of_a_vpc_and_bad_ones_are_clear_errors() {
    let dir = scratch("info");
    let path = grid(&dir, 2);
    let o = surfel(&["info", path.to_str().unwrap()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let out = String::from_utf8(o.stdout).unwrap();
    let lines: Vec<&str> = out.lines().collect();
    assert_eq!(
        lines[1],
        "format            virtual point cloud (STAC ItemCollection)"
    );
    assert_eq!(lines[2], "tiles             4");
    assert_eq!(lines[3], "points            25600");
    // x and y from the tiles' proj:bbox (the sheet's z is between 95 and 105).
    let bounds: Vec<&str> = lines[4].split_whitespace().collect();
    assert_eq!(bounds[..3], ["bounds", "500000.250", "4000000.250"]);
    assert_eq!(bounds[4..7], ["..", "500079.750", "4000079.750"]);
    let z: Vec<f64> = [bounds[3], bounds[7]].map(|v| v.parse().unwrap()).to_vec();
    assert!(95.0 <= z[0] && z[0] < z[1] && z[1] <= 105.0, "{z:?}");
    assert_eq!(lines[5], "crs               none");
    assert_eq!(lines.len(), 10);
    assert!(lines[6].starts_with("  t00 "), "{}", lines[6]);
    assert!(lines[6].contains("6400 points  application/vnd.laszip+copc  ./tiles/t00.copc.laz"));
    let bad = dir.join("bad.vpc");
    std::fs::write(
        &bad,
        "{\"type\": \"FeatureCollection\",\n \"features\": [{\"type\": \"Feature\"}]}",
    )
    .unwrap();
    for command in ["info", "render"] {
        let o = surfel(&[command, bad.to_str().unwrap()]);
        assert!(!o.status.success());
        let err = String::from_utf8(o.stderr).unwrap();
        assert!(
            err.contains(&format!("{}: feature 0: missing field `id`", bad.display())),
            "{err}"
        );
    }
}

#[test]
fn requests_are_capped_and_retried_across_tiles() {
    let dir = scratch("retries");
    grid(&dir, 2);
    // Every tile's first two requests fail with 503: each is retried.
    let server = serve(dir.clone(), |p, attempt| {
        (p.starts_with("/tiles/") && attempt < 2).then_some(503)
    });
    let url = format!("{}/grid.vpc", server.url);
    let mut options = options(u64::MAX);
    options.loader.threads = 4;
    options.loader.http.connections = 1;
    let s = stream(&url, &options, &framing, 96);
    assert!(s.messages.is_empty(), "{:?}", s.messages);
    assert_eq!(s.stats.drawn_points, 4 * 6400);
    assert_eq!(server.most_at_once.load(Ordering::SeqCst), 1);
}

#[test]
fn a_clip_box_spans_the_tiles() {
    use surfel::scene::clip::{ClipBox, Filter};
    let dir = scratch("clip");
    let path = grid(&dir, 2);
    // The same tiles 0 and 2 (x below 500,040) in a .vpc of their own.
    let text = std::fs::read_to_string(&path).unwrap();
    let mut json: Value = serde_json::from_str(&text).unwrap();
    let features = json["features"].as_array_mut().unwrap();
    features.retain(|f| f["id"] == "t00" || f["id"] == "t02");
    let left = dir.join("left.vpc");
    std::fs::write(&left, serde_json::to_string(&json).unwrap()).unwrap();
    // One view of the grid's centre, from file coordinates.
    let camera = |s: &StreamedScene| {
        let centre = (DVec3::new(500_040.0, 4_000_040.0, 100.0) - s.origin()).as_vec3();
        Camera::look_at_up(Up::Z, centre + Vec3::new(0.0, -60.0, 90.0), centre, 1.0)
    };
    let filter = Filter {
        clip: Some(ClipBox::aligned(
            DVec3::new(499_990.0, 3_999_990.0, 0.0),
            DVec3::new(500_040.0, 4_000_090.0, 200.0),
        )),
        ..Filter::default()
    };
    let clipped = stream_filtered(
        path.to_str().unwrap(),
        &options(u64::MAX),
        &camera,
        128,
        Some(&filter),
    );
    let half = stream(left.to_str().unwrap(), &options(u64::MAX), &camera, 128);
    assert_eq!(clipped.stats.drawn_points, 4 * 6400);
    assert_eq!(half.stats.drawn_points, 2 * 6400);
    let covered = |f: &Frame| (0..f.pixels()).filter(|&i| f.covered(i)).count();
    assert!(
        covered(&half.frame) > 128 * 128 / 10,
        "{}",
        covered(&half.frame)
    );
    let differ = (0..half.frame.pixels())
        .filter(|&i| half.frame.covered(i) != clipped.frame.covered(i))
        .count();
    // The two scenes' origins differ: positions round differently in single precision.
    assert!(
        differ <= covered(&half.frame) / 100,
        "{differ} pixels differ"
    );
}
