//! The viewer end to end under Xvfb with validation (and synchronization validation) on:
//! scripted tours that show and hide the HUD, take screenshots, save and load the camera and
//! resize the window; script errors; the window sized to the monitor.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use image::RgbImage;

pub(crate) fn data(rel: &str) -> PathBuf {
    let root = std::env::var_os("SURFEL_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data"));
    root.join(rel)
}

/// A fresh directory for one test.
pub(crate) fn tmp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("surfel-viewer-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("temp dir");
    dir
}

/// Runs `surfel view FILE args` under `xvfb-run` (screen `screen`) in `dir`.
pub(crate) fn view(dir: &Path, screen: &str, file: &Path, args: &[&str]) -> Output {
    Command::new("xvfb-run")
        .args(["-a", "-s", &format!("-screen 0 {screen}x24")])
        .arg(env!("CARGO_BIN_EXE_surfel"))
        .arg("view")
        .arg(file)
        .args(args)
        .arg("--validation")
        .current_dir(dir)
        .env("XDG_RUNTIME_DIR", std::env::temp_dir())
        .output()
        .expect("xvfb-run is installed by ../shared/ci/install-vulkan.sh")
}

pub(crate) fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

fn png(path: &Path) -> RgbImage {
    image::open(path)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
        .to_rgb8()
}

fn bright(p: &image::Rgb<u8>) -> bool {
    p.0.iter().all(|&c| c >= 200)
}

/// Pixels where `a` and `b` differ, and their bounding box (x0, y0, x1, y1), inclusive.
fn difference(a: &RgbImage, b: &RgbImage) -> (usize, Option<(u32, u32, u32, u32)>) {
    assert_eq!(a.dimensions(), b.dimensions());
    let mut n = 0;
    let mut bbox: Option<(u32, u32, u32, u32)> = None;
    for (x, y, p) in a.enumerate_pixels() {
        if p != b.get_pixel(x, y) {
            n += 1;
            bbox = Some(match bbox {
                None => (x, y, x, y),
                Some((x0, y0, x1, y1)) => (x0.min(x), y0.min(y), x1.max(x), y1.max(y)),
            });
        }
    }
    (n, bbox)
}

#[test]
fn a_scripted_tour_shows_and_hides_the_hud_saves_and_loads_the_camera_and_resizes() {
    let dir = tmp_dir("tour");
    let las = data("lidar/autzen_trim.las");
    std::fs::write(
        dir.join("tour.txt"),
        "# the HUD on, then off\n\
         frames 2\n\
         screenshot hud.png\n\
         key Tab\n\
         screenshot plain.png\n\
         key K              # save the camera\n\
         orbit 120,5\n\
         screenshot turned.png\n\
         key L              # and load it back\n\
         screenshot loaded.png\n\
         key Tab\n\
         key H\n\
         screenshot help.png\n\
         key h\n\
         key c\n\
         key m\n\
         size 320x200\n\
         screenshot small.png\n",
    )
    .expect("script");
    let o = view(
        &dir,
        "1024x768",
        &las,
        &[
            "--size",
            "480x360",
            "--orbit",
            "30,20",
            "--script",
            "tour.txt",
            "--camera-file",
            "cam.toml",
        ],
    );
    assert!(o.status.success(), "viewer failed: {}", text(&o.stderr));
    let stdout = text(&o.stdout);
    for line in [
        "screenshot hud.png",
        "screenshot plain.png",
        "camera saved to cam.toml",
        "camera loaded from cam.toml",
        "screenshot small.png",
    ] {
        assert!(
            stdout.lines().any(|l| l == line),
            "{line:?} not in {stdout}"
        );
    }

    // The HUD: a panel from (MARGIN, MARGIN) with bright text on it, the rest untouched.
    let (hud, plain) = (png(&dir.join("hud.png")), png(&dir.join("plain.png")));
    assert_eq!(hud.dimensions(), (480, 360));
    let (changed, bbox) = difference(&hud, &plain);
    let (x0, y0, x1, y1) = bbox.expect("the HUD changed the image");
    let margin = surfel::overlay::MARGIN as u32;
    assert_eq!(
        (x0, y0),
        (margin, margin),
        "the panel hangs from the top-left margin"
    );
    let area = (x1 - x0 + 1) * (y1 - y0 + 1);
    assert!(
        area < 480 * 360 / 2 && x1 < 400 && y1 < 300,
        "the HUD covers only a corner: {bbox:?}"
    );
    // The translucent panel changes (almost) every pixel under it.
    assert!(changed as f64 > 0.95 * area as f64, "{changed} of {area}");
    let text_pixels = (y0..=y1)
        .flat_map(|y| (x0..=x1).map(move |x| (x, y)))
        .filter(|&(x, y)| bright(hud.get_pixel(x, y)) && !bright(plain.get_pixel(x, y)))
        .count();
    assert!(text_pixels > 300, "only {text_pixels} bright text pixels");

    // The camera file holds the --orbit 30,20 camera and loading it restores the view.
    let cam = surfel::scene::scene_file::SceneFile::load(&dir.join("cam.toml")).expect("parses");
    let cloud = surfel::scene::load(&las).expect("autzen");
    let (centre, radius) = cloud.bounding_sphere().expect("points");
    let up = surfel::scene::Up::Z;
    let expected = surfel::scene::Camera::orbit_about(up, centre, radius, 30.0, 20.0, 1.0);
    assert_eq!(cam.up, Some(up));
    let Some(surfel::scene::camera::Pose::LookAt { eye, target }) = cam.camera else {
        panic!("no look-at camera in {:?}", cam.camera);
    };
    assert!(
        ((glam::DVec3::from(eye) - cloud.origin).as_vec3() - expected.eye).length() < 1e-4 * radius,
        "{eye:?} vs {}",
        expected.eye
    );
    assert!(
        ((glam::DVec3::from(target) - cloud.origin).as_vec3() - expected.target).length()
            < 1e-4 * radius
    );
    let (turned, _) = difference(&plain, &png(&dir.join("turned.png")));
    assert!(
        turned > 480 * 360 / 20,
        "orbit 120,5 changed only {turned} pixels"
    );
    let (loaded, _) = difference(&plain, &png(&dir.join("loaded.png")));
    assert!(
        loaded < 480 * 360 / 200,
        "the loaded camera differs in {loaded} pixels"
    );

    // Help: a second panel hangs from the top-right margin.
    let help = png(&dir.join("help.png"));
    let (_, bbox) = difference(&help, &plain);
    let (_, _, x1, _) = bbox.expect("HUD and help drawn");
    assert_eq!(
        x1,
        480 - margin - 1,
        "the help panel reaches the right margin"
    );

    // After the resize, the frame (and the HUD) have the new size.
    assert_eq!(png(&dir.join("small.png")).dimensions(), (320, 200));
}

/// Sum of the RGB channels.
fn brightness(img: &RgbImage) -> u64 {
    img.pixels().flat_map(|p| p.0).map(u64::from).sum()
}

#[test]
fn a_lidar_tour_switches_color_by_and_eye_dome_lighting_with_the_hud_shown() {
    // A LiDAR tour: a LAS file, the HUD, color-by and EDL switched by keys, screenshots.
    let dir = tmp_dir("lidar");
    std::fs::write(
        dir.join("tour.txt"),
        "frames 2\n\
         screenshot hud.png\n\
         key Tab\n\
         screenshot intensity.png\n\
         key E              # eye-dome lighting on\n\
         screenshot edl.png\n\
         key E              # and off\n\
         key V              # intensity -> classification\n\
         screenshot classes.png\n\
         key Tab\n\
         key E\n\
         screenshot classes-edl-hud.png\n",
    )
    .expect("script");
    let o = view(
        &dir,
        "1024x768",
        &data("lidar/autzen_trim.las"),
        &[
            "--size",
            "400x300",
            "--color-by",
            "intensity",
            "--script",
            "tour.txt",
        ],
    );
    assert!(o.status.success(), "viewer failed: {}", text(&o.stderr));
    let stdout = text(&o.stdout);
    assert!(
        stdout.lines().any(|l| l == "color by classification"),
        "{stdout}"
    );
    let intensity = png(&dir.join("intensity.png"));
    let edl = png(&dir.join("edl.png"));
    let classes = png(&dir.join("classes.png"));
    // EDL only darkens: some pixels change, none gets brighter.
    let (darkened, _) = difference(&intensity, &edl);
    assert!(darkened > 100, "EDL changed only {darkened} pixels");
    assert!(intensity.pixels().zip(edl.pixels()).all(|(a, b)| a
        .0
        .iter()
        .zip(b.0)
        .all(|(x, y)| y <= *x)));
    assert!(brightness(&edl) < brightness(&intensity));
    // Classification colors (unlit palette): ground is class 2.
    let ground = [0xa0, 0x72, 0x4a];
    let ground_pixels = classes.pixels().filter(|p| p.0 == ground).count();
    assert!(
        ground_pixels > 1000,
        "{ground_pixels} ground-colored pixels"
    );
    assert_eq!(intensity.pixels().filter(|p| p.0 == ground).count(), 0);
    // With the HUD shown again, its panel (and the legend) is drawn over the EDL image.
    let hud = png(&dir.join("classes-edl-hud.png"));
    let (changed, bbox) = difference(&classes, &hud);
    assert!(changed > 0 && bbox.is_some());
    assert_eq!(hud.dimensions(), (400, 300));
}

#[test]
fn g_cycles_the_number_of_lights() {
    let dir = tmp_dir("lights");
    // From the headlight: 2, ..., 9, then none, then the headlight again.
    let mut script = String::from("key Tab\nscreenshot one.png\n");
    script.push_str(&"key g\n".repeat(8));
    script.push_str("screenshot nine.png\nkey g\nscreenshot none.png\nkey g\n");
    std::fs::write(dir.join("t.txt"), script).expect("script");
    let o = view(
        &dir,
        "800x600",
        &data("stanford/bun_zipper.ply"),
        &["--size", "200x160", "--script", "t.txt"],
    );
    assert!(o.status.success(), "viewer failed: {}", text(&o.stderr));
    let stdout = text(&o.stdout);
    for line in ["lights: 2", "lights: 9", "lights: 0", "lights: 1"] {
        assert!(
            stdout.lines().any(|l| l == line),
            "{line:?} not in {stdout}"
        );
    }
    let none = brightness(&png(&dir.join("none.png")));
    let one = brightness(&png(&dir.join("one.png")));
    let nine = brightness(&png(&dir.join("nine.png")));
    // Ambient only is darkest; the ring of nine splits one light's intensity off-axis.
    assert!(none < one && none < nine, "{none} {one} {nine}");
    assert_ne!(one, nine);
}

#[test]
fn bracket_keys_step_through_the_pyramid_levels() {
    // `]` from the reconstruction shows level 0 as projected (1 pixel per point: far fewer
    // covered pixels), then level 1 magnified; `[` twice returns to the reconstruction.
    let dir = tmp_dir("levels");
    std::fs::write(
        dir.join("t.txt"),
        "key Tab\nscreenshot full.png\nkey ]\nscreenshot raw.png\nkey ]\nscreenshot one.png\n\
         key [\nkey [\nscreenshot back.png\n",
    )
    .expect("script");
    let o = view(
        &dir,
        "800x600",
        &data("stanford/bun_zipper.ply"),
        &[
            "--size", "640x480", "--method", "pyramid", "--script", "t.txt",
        ],
    );
    assert!(o.status.success(), "viewer failed: {}", text(&o.stderr));
    let stdout = text(&o.stdout);
    for line in [
        "showing level 0 as projected",
        "showing level 1 of the analysis",
        "showing the reconstruction",
    ] {
        assert!(
            stdout.lines().any(|l| l == line),
            "{line:?} not in {stdout}"
        );
    }
    let covered = |name: &str| {
        png(&dir.join(name))
            .pixels()
            .filter(|p| p.0 != [0, 0, 0])
            .count()
    };
    let (full, raw, one) = (covered("full.png"), covered("raw.png"), covered("one.png"));
    assert!(raw * 4 < full * 3, "level 0 {raw} vs reconstruction {full}");
    assert!(one > raw, "level 1 magnified {one} vs level 0 {raw}");
    assert_eq!(
        difference(&png(&dir.join("full.png")), &png(&dir.join("back.png"))).0,
        0
    );
}

#[test]
fn without_size_the_window_takes_80_percent_of_the_monitor() {
    let dir = tmp_dir("monitor");
    std::fs::write(dir.join("s.txt"), "screenshot full.png\nquit\nframes 100\n").expect("script");
    let o = view(
        &dir,
        "500x400",
        &data("stanford/bun_zipper.ply"),
        &["--script", "s.txt"],
    );
    assert!(o.status.success(), "viewer failed: {}", text(&o.stderr));
    assert_eq!(png(&dir.join("full.png")).dimensions(), (400, 320));
}

#[test]
fn a_bad_script_line_names_the_file_and_line() {
    let dir = tmp_dir("bad");
    std::fs::write(dir.join("bad.txt"), "frames 1\n# fine\nkey Space\n").expect("script");
    let o = Command::new(env!("CARGO_BIN_EXE_surfel"))
        .args(["view"])
        .arg(data("stanford/bun_zipper.ply"))
        .args(["--script", "bad.txt"])
        .current_dir(&dir)
        .output()
        .expect("run surfel");
    let stderr = text(&o.stderr);
    assert!(!o.status.success());
    assert!(
        stderr.contains("bad.txt:3: expected `key NAME` with NAME a letter, a digit, ctrl+DIGIT"),
        "{stderr}"
    );
    assert!(!stderr.contains("panicked"), "{stderr}");
    let o = Command::new(env!("CARGO_BIN_EXE_surfel"))
        .args(["view"])
        .arg(data("stanford/bun_zipper.ply"))
        .args(["--camera-file", "cam.txt"])
        .current_dir(&dir)
        .output()
        .expect("run surfel");
    assert!(!o.status.success());
    assert!(text(&o.stderr).contains("cam.txt: camera files are scene files"));
}

#[test]
fn a_failing_script_step_stops_the_viewer_with_its_error() {
    let dir = tmp_dir("fail");
    std::fs::write(dir.join("s.txt"), "frames 1\nkey L\nframes 5\n").expect("script");
    let o = view(
        &dir,
        "640x480",
        &data("stanford/bun_zipper.ply"),
        &[
            "--size",
            "64x48",
            "--script",
            "s.txt",
            "--camera-file",
            "none.toml",
        ],
    );
    assert!(!o.status.success());
    let stderr = text(&o.stderr);
    assert!(
        stderr.contains("none.toml: cannot read scene file"),
        "{stderr}"
    );
    assert!(!stderr.contains("panicked"), "{stderr}");
}

#[test]
fn switching_to_ewa_and_phong_uploads_their_normal_fields() {
    // Started on the pyramid, whose upload has no normal fields: `n` steps back to EWA, then to
    // perspective-phong, which read them, so the viewer adds their stream to the scene
    // (under validation); `m` twice returns to the pyramid's image.
    let dir = tmp_dir("fields");
    std::fs::write(
        dir.join("t.txt"),
        "key Tab\nscreenshot pyramid.png\nkey n\nscreenshot ewa.png\nkey n\n\
         screenshot phong.png\nkey m\nkey m\nscreenshot back.png\n",
    )
    .expect("script");
    let o = view(
        &dir,
        "800x600",
        &data("stanford/bun_zipper.ply"),
        &[
            "--size", "320x240", "--method", "pyramid", "--script", "t.txt",
        ],
    );
    assert!(o.status.success(), "viewer failed: {}", text(&o.stderr));
    let stdout = text(&o.stdout);
    let switched: Vec<&str> = stdout
        .lines()
        .filter(|l| l.starts_with("method "))
        .collect();
    assert_eq!(
        switched,
        [
            "method ewa",
            "method perspective-phong",
            "method ewa",
            "method pyramid"
        ]
    );
    let shot = |name: &str| png(&dir.join(name));
    let (pyramid, ewa, phong) = (shot("pyramid.png"), shot("ewa.png"), shot("phong.png"));
    assert!(
        difference(&pyramid, &ewa).0 > 100,
        "EWA shows the pyramid's image"
    );
    assert!(difference(&ewa, &phong).0 > 100, "Phong shows EWA's image");
    assert_eq!(difference(&pyramid, &shot("back.png")).0, 0);
}

#[test]
fn a_raw_cloud_is_drawn_at_once_and_lit_when_its_normals_are_estimated() {
    // A LAS file without normals, started on the compute rasterizer: the viewer estimates
    // normals and radii in the background (a script waits for them before its first step),
    // then uploads the cloud again, lit: the plain base color turns into shades. `m` twice
    // reaches the first splat method, which reads them; `n` twice returns to compute.
    let dir = tmp_dir("estimate");
    std::fs::write(
        dir.join("t.txt"),
        "key Tab\nkey m\nkey m\nkey n\nkey n\nscreenshot lit.png\n",
    )
    .expect("script");
    let o = view(
        &dir,
        "800x600",
        &data("lidar/autzen_trim.las"),
        &[
            "--size",
            "320x240",
            "--method",
            "compute",
            "--color-by",
            "none",
            "--script",
            "t.txt",
        ],
    );
    assert!(o.status.success(), "viewer failed: {}", text(&o.stderr));
    let stdout = text(&o.stdout);
    let ready = stdout
        .lines()
        .position(|l| l.starts_with("normals and radii ready after "));
    let splats = stdout.lines().position(|l| l == "method points-flat");
    assert!(
        ready.is_some() && splats.is_some() && ready < splats,
        "{stdout}"
    );
    let lit = png(&dir.join("lit.png"));
    let shades: std::collections::BTreeSet<u8> = lit.pixels().map(|p| p.0[1]).collect();
    assert!(shades.len() > 20, "{} shades of grey", shades.len());
}

#[test]
fn a_streamed_file_is_toured_with_budget_keys_and_methods_that_draw_streams() {
    // A COPC of the LiDAR tile streamed by view: the HUD shows the streaming line; `,` halves
    // the point budget (fewer points drawn), `.` restores it; `M` skips the methods that read
    // the whole cloud.
    let dir = tmp_dir("stream");
    let cloud = surfel::scene::load(&data("lidar/autzen_trim.las")).expect("load");
    let copc = dir.join("autzen.copc.laz");
    surfel::copc::convert::write_with(&cloud, &copc, 5_000).expect("convert");
    std::fs::write(
        dir.join("tour.txt"),
        "key Tab\n\
         screenshot full.png\n\
         key ,\nkey ,\nkey ,\n\
         screenshot fewer.png\n\
         key .\nkey .\nkey .\n\
         screenshot again.png\n\
         count\nfilter only 9\ncount\nfilter all\n\
         clip box 636000 848900 300 636590 849600 700\ncount\nclip off\npick 160 120\n\
         key Tab\n\
         screenshot hud.png\n\
         key M\nkey M\nkey M\nkey M\nkey M\nkey M\n\
         screenshot method.png\n",
    )
    .expect("script");
    let o = view(
        &dir,
        "800x600",
        &copc,
        &[
            "--size",
            "320x240",
            "--stream",
            "--point-budget",
            "80000",
            "--gpu-budget",
            "64M",
            "--script",
            "tour.txt",
        ],
    );
    assert!(o.status.success(), "viewer failed: {}", text(&o.stderr));
    let stdout = text(&o.stdout);
    assert!(
        stdout.lines().any(|l| l == "point budget 10000"),
        "{stdout}"
    );
    assert!(
        stdout.lines().any(|l| l == "point budget 80000"),
        "{stdout}"
    );
    // The class filter and the box apply to the streamed nodes too (the nodes carry the class
    // stream); a pick reads the drawn nodes under the cursor again and finds a point of the
    // file, with its node and attributes.
    let counts: Vec<u64> = stdout
        .lines()
        .filter_map(|l| serde_json::from_str::<serde_json::Value>(l).ok())
        .filter_map(|v| v["count"]["covered_pixels"].as_u64())
        .collect();
    assert_eq!(counts.len(), 3, "{stdout}");
    assert_eq!(counts[1], 0, "no point is of class 9: {counts:?}");
    assert!(
        counts[2] < counts[0] * 3 / 4 && counts[2] > 0,
        "the box: {counts:?}"
    );
    let pick = stdout
        .lines()
        .filter_map(|l| serde_json::from_str::<serde_json::Value>(l).ok())
        .find_map(|v| v.get("pick").cloned())
        .unwrap_or_else(|| panic!("no pick: {stdout}"));
    let point = &pick["point"];
    assert!(
        point["node"]
            .as_str()
            .is_some_and(|n| n.contains("autzen.copc.laz node ")),
        "{pick}"
    );
    assert!(point["attributes"]["classification"].is_number(), "{pick}");
    let at: Vec<f64> = (0..3)
        .map(|k| point["position"][k].as_f64().unwrap())
        .collect();
    let nearest = cloud
        .positions
        .iter()
        .map(|p| {
            let w = cloud.origin + p.as_dvec3();
            (w - glam::DVec3::from_slice(&at)).length()
        })
        .fold(f64::INFINITY, f64::min);
    assert!(
        nearest < 0.01,
        "{pick}: {nearest} m from a point of the file"
    );
    let methods: Vec<&str> = stdout
        .lines()
        .filter_map(|l| l.strip_prefix("method "))
        .collect();
    assert_eq!(methods.len(), 6, "{stdout}");
    for m in &methods {
        assert!(
            !m.starts_with("lod")
                && !m.starts_with("hpr")
                && *m != "mesh"
                && !m.ends_with("-phong"),
            "{m} reads what a streamed file does not have: {stdout}"
        );
    }
    let lit = |name: &str| {
        png(&dir.join(name))
            .pixels()
            .filter(|p| p.0 != [0, 0, 0])
            .count()
    };
    let (full, fewer) = (lit("full.png"), lit("fewer.png"));
    assert!(
        fewer * 4 < full * 3,
        "budget 10,000: {fewer} pixels vs {full}"
    );
    assert_eq!(
        difference(&png(&dir.join("full.png")), &png(&dir.join("again.png"))).0,
        0
    );
    let (changed, _) = difference(&png(&dir.join("again.png")), &png(&dir.join("hud.png")));
    assert!(changed > 0);
}

#[test]
fn a_missing_screenshot_directory_is_created() {
    let dir = tmp_dir("shots");
    std::fs::write(dir.join("t.txt"), "frames 1\nkey P\nframes 1\n").expect("script");
    let o = view(
        &dir,
        "800x600",
        &data("stanford/bun_zipper.ply"),
        &[
            "--size",
            "160x120",
            "--screenshot-dir",
            "shots/new",
            "--script",
            "t.txt",
        ],
    );
    assert!(o.status.success(), "viewer failed: {}", text(&o.stderr));
    assert_eq!(
        png(&dir.join("shots/new/surfel-1.png")).dimensions(),
        (160, 120)
    );
    // A path that cannot be a directory is refused with the reason.
    std::fs::write(dir.join("file"), "").expect("file");
    let o = view(
        &dir,
        "800x600",
        &data("stanford/bun_zipper.ply"),
        &["--screenshot-dir", "file/sub", "--frames", "1"],
    );
    assert!(!o.status.success());
    let err = text(&o.stderr);
    assert!(
        err.contains("file/sub: cannot create the screenshot directory"),
        "{err}"
    );
}

#[test]
fn key_p_then_a_screenshot_writes_both_from_the_same_frame() {
    let dir = tmp_dir("p-then-shot");
    std::fs::write(
        dir.join("t.txt"),
        "frames 1\nkey Tab\nkey P\nscreenshot b.png\nkey P\nkey P\norbit 90,10\nscreenshot c.png\n",
    )
    .expect("script");
    let o = view(
        &dir,
        "800x600",
        &data("stanford/bun_zipper.ply"),
        &["--size", "160x120", "--script", "t.txt"],
    );
    assert!(o.status.success(), "viewer failed: {}", text(&o.stderr));
    let stdout = text(&o.stdout);
    let written: Vec<&str> = stdout
        .lines()
        .filter(|l| l.starts_with("screenshot "))
        .collect();
    assert_eq!(
        written,
        [
            "screenshot surfel-1.png",
            "screenshot b.png",
            "screenshot surfel-2.png",
            "screenshot surfel-3.png",
            "screenshot c.png",
        ],
        "{stdout}"
    );
    let shot = |name: &str| png(&dir.join(name));
    assert_eq!(difference(&shot("surfel-1.png"), &shot("b.png")).0, 0);
    assert_eq!(difference(&shot("surfel-2.png"), &shot("c.png")).0, 0);
    assert_eq!(difference(&shot("surfel-3.png"), &shot("c.png")).0, 0);
    assert!(difference(&shot("b.png"), &shot("c.png")).0 > 100);
}

#[test]
fn key_v_in_a_streamed_tour_is_reported_and_the_tour_goes_on() {
    let dir = tmp_dir("stream-v");
    let cloud = surfel::scene::load(&data("stanford/bun_zipper.ply")).expect("load");
    let copc = dir.join("bunny.copc.laz");
    surfel::copc::convert::write_with(&cloud, &copc, 5_000).expect("convert");
    std::fs::write(dir.join("t.txt"), "frames 1\nkey V\nscreenshot after.png\n").expect("script");
    let o = view(
        &dir,
        "800x600",
        &copc,
        &["--size", "160x120", "--stream", "--script", "t.txt"],
    );
    assert!(o.status.success(), "viewer failed: {}", text(&o.stderr));
    let stdout = text(&o.stdout);
    let e = "V is off for a streamed file: its colour field is chosen when it opens (--color-by)";
    let lines: Vec<&str> = stdout.lines().collect();
    let json = serde_json::json!({ "error": e }).to_string();
    let at = lines
        .iter()
        .position(|l| *l == json)
        .unwrap_or_else(|| panic!("no error line: {stdout}"));
    assert_eq!(lines[at + 1], e);
    assert!(
        lines[at + 2..].contains(&"screenshot after.png"),
        "{stdout}"
    );
    assert_eq!(png(&dir.join("after.png")).dimensions(), (160, 120));
}

#[test]
fn a_camera_path_is_played_timed_at_every_frame_and_written() {
    let dir = tmp_dir("path");
    std::fs::write(
        dir.join("flight.toml"),
        "frames = 5\n[[keys]]\ntime = 0\ncamera = { orbit = [0.0, 10.0] }\n\
         [[keys]]\ntime = 2\ncamera = { orbit = [60.0, 20.0], distance = 0.6 }\n",
    )
    .expect("path");
    let bunny = data("stanford/bun_zipper.ply");
    let o = view(
        &dir,
        "1024x768",
        &bunny,
        &[
            "--size",
            "160x120",
            "--path",
            "flight.toml",
            "--warmup",
            "2",
            "--timings",
            "t.json",
            "--timings-csv",
            "t.csv",
            "--trace",
            "trace.json",
        ],
    );
    // With outputs asked for, the viewer quits after the flight.
    assert!(o.status.success(), "viewer failed: {}", text(&o.stderr));
    assert!(
        text(&o.stdout).contains("path: 5 frames, GPU "),
        "{}",
        text(&o.stdout)
    );
    let read = |name: &str| std::fs::read_to_string(dir.join(name)).expect(name);
    let t: serde_json::Value = serde_json::from_str(&read("t.json")).expect("json");
    assert_eq!(t["meta"]["present_mode"], "fifo");
    assert_eq!(
        (t["meta"]["width"].as_u64(), t["meta"]["height"].as_u64()),
        (Some(160), Some(120))
    );
    assert_eq!(t["plan"]["warmup"], 2);
    assert_eq!(t["plan"]["frames"], 5);
    assert_eq!(
        t["path_times"],
        serde_json::json!([0.0, 0.5, 1.0, 1.5, 2.0])
    );
    let passes = t["passes"].as_array().expect("passes");
    let names: Vec<&str> = passes.iter().filter_map(|p| p["name"].as_str()).collect();
    assert!(
        names.contains(&"points.project") && names.contains(&"overlay.text"),
        "{names:?}"
    );
    for p in passes.iter().chain([&t["frame"]]) {
        let samples = p["samples_ms"].as_array().expect("samples");
        assert_eq!(samples.len(), 5, "{p}");
        assert!(
            samples
                .iter()
                .all(|s| s.as_f64().is_some_and(|ms| ms > 0.0)),
            "{p}"
        );
    }
    // The tidy CSV: one row per frame and pass.
    assert_eq!(read("t.csv").lines().count(), 1 + 5 * passes.len());
    let trace: serde_json::Value = serde_json::from_str(&read("trace.json")).expect("trace");
    assert!(trace["traceEvents"]
        .as_array()
        .is_some_and(|e| !e.is_empty()));
}

#[test]
fn viewer_timings_without_a_path_are_refused() {
    let dir = tmp_dir("timings-no-path");
    let bunny = data("stanford/bun_zipper.ply");
    let o = view(&dir, "640x480", &bunny, &["--timings", "t.json"]);
    assert!(!o.status.success());
    assert!(
        text(&o.stderr).contains("time a camera path in the viewer: give --path"),
        "{}",
        text(&o.stderr)
    );
}
