//! The viewer's tools under Xvfb with validation on, driven by scripts that print JSON:
//! picking (through the depth buffer and hidden point removal), measuring in a UTM-sized
//! file's coordinates, the class filter and the clipping boxes against the CPU's count, and
//! the camera file keeping them.

use std::path::Path;

use serde_json::Value;

use super::viewer::{data, text, tmp_dir, view};

/// The JSON lines of the viewer's stdout whose single key is `key`.
fn records(stdout: &str, key: &str) -> Vec<Value> {
    stdout
        .lines()
        .filter(|l| l.starts_with('{'))
        .map(|l| serde_json::from_str::<Value>(l).unwrap_or_else(|e| panic!("{l}: {e}")))
        .filter_map(|v| v.get(key).cloned())
        .collect()
}

/// The `count` records of a tour: covered pixels and kept points.
fn counts(stdout: &str) -> Vec<(u64, u64)> {
    records(stdout, "count")
        .iter()
        .map(|c| {
            (
                c["covered_pixels"].as_u64().expect("pixels"),
                c["kept_points"].as_u64().expect("kept"),
            )
        })
        .collect()
}

/// Writes an ASCII PLY of `points` (x, y, z as written) with a `classification` column when
/// `classes` is given.
fn write_ply(path: &Path, points: &[[f64; 3]], classes: Option<&[u8]>) {
    let mut s = format!(
        "ply\nformat ascii 1.0\nelement vertex {}\nproperty double x\nproperty double y\n\
         property double z\n",
        points.len()
    );
    if classes.is_some() {
        s.push_str("property uchar classification\n");
    }
    s.push_str("end_header\n");
    for (i, p) in points.iter().enumerate() {
        s.push_str(&format!("{} {} {}", p[0], p[1], p[2]));
        if let Some(c) = classes {
            s.push_str(&format!(" {}", c[i]));
        }
        s.push('\n');
    }
    std::fs::write(path, s).expect("write ply");
}

fn run(dir: &Path, file: &Path, script: &str, args: &[&str]) -> String {
    std::fs::write(dir.join("t.txt"), script).expect("script");
    let mut all = vec!["--size", "320x240", "--script", "t.txt"];
    all.extend_from_slice(args);
    let o = view(dir, "800x600", file, &all);
    assert!(o.status.success(), "viewer failed: {}", text(&o.stderr));
    text(&o.stdout)
}

fn f(v: &Value) -> f64 {
    v.as_f64().unwrap_or_else(|| panic!("not a number: {v}"))
}

#[test]
fn a_pick_returns_the_drawn_point_and_never_one_behind_a_sparse_wall() {
    let dir = tmp_dir("walls");
    // A sparse front wall (0.2 apart) at z = 0 and a dense back wall (0.02 apart) at z = -3,
    // seen from z = 4: between the front points the depth buffer shows the back wall.
    let mut points = Vec::new();
    for i in 0..=10 {
        for j in 0..=10 {
            points.push([-1.0 + 0.2 * f64::from(i), -1.0 + 0.2 * f64::from(j), 0.0]);
        }
    }
    let front = points.len();
    for i in 0..=200 {
        for j in 0..=200 {
            points.push([-2.0 + 0.02 * f64::from(i), -2.0 + 0.02 * f64::from(j), -3.0]);
        }
    }
    let ply = dir.join("walls.ply");
    write_ply(&ply, &points, None);
    let mut script = String::from("frames 2\nlocate 0.2 0.4 0\nlocate -0.6 0 0\n");
    for x in (100..=220).step_by(5) {
        script.push_str(&format!("pick {x} 121\n"));
    }
    let camera = ["--eye", "0,0,4", "--target", "0,0,0", "--k", "0"];
    let stdout = run(&dir, &ply, &script, &camera);
    let picks = records(&stdout, "pick");
    assert_eq!(picks.len(), 25, "{stdout}");
    let mut back_shown = 0;
    let mut hidden = 0;
    for p in &picks {
        let point = p["point"]
            .as_object()
            .unwrap_or_else(|| panic!("nothing picked: {p}"));
        let index = point["index"].as_u64().expect("index") as usize;
        let z = f(&point["position"][2]);
        assert!(
            index < front && z == 0.0,
            "picked behind the front wall: {p}"
        );
        if p["buffer_depth"]
            .as_f64()
            .is_some_and(|d| (d - 7.0).abs() < 0.01)
        {
            back_shown += 1;
        }
        hidden += p["hidden_by_hpr"].as_u64().expect("count");
    }
    // The scenario is real: the depth buffer showed the back wall at most picked pixels, and
    // only hidden point removal kept those back points from being picked.
    assert!(
        back_shown >= 15,
        "back wall shown at {back_shown} of 25 pixels"
    );
    assert!(hidden > 0);

    // Where the depth buffer shows a front point, a pick there returns that very point.
    let located = records(&stdout, "locate");
    let mut script = String::from("frames 2\n");
    for l in &located {
        script.push_str(&format!("pick {} {}\n", l["pixel"][0], l["pixel"][1]));
    }
    let stdout = run(&dir, &ply, &script, &camera);
    let picks = records(&stdout, "pick");
    for (l, p) in located.iter().zip(&picks) {
        assert_eq!(p["point"]["drawn_at"], l["pixel"], "{p}");
        for axis in 0..3 {
            let (got, want) = (&p["point"]["position"][axis], &l["position"][axis]);
            assert!((f(got) - f(want)).abs() < 1e-6, "{p}");
        }
        let (d, buffer) = (f(&p["point"]["view_depth"]), f(&p["buffer_depth"]));
        assert!((d - buffer).abs() <= 1e-5 * buffer, "{d} vs {buffer}");
    }
    assert_eq!(picks.len(), 2);
}

#[test]
fn picks_on_a_scan_return_the_point_its_depth_buffer_shows() {
    let dir = tmp_dir("bunny-pick");
    let mut script = String::from("frames 2\n");
    for (x, y) in [(160, 120), (150, 100), (170, 140), (140, 130), (180, 110)] {
        script.push_str(&format!("pick {x} {y}\n"));
    }
    let stdout = run(
        &dir,
        &data("stanford/bun_zipper.ply"),
        &script,
        &["--method", "compute"],
    );
    let picks = records(&stdout, "pick");
    assert_eq!(picks.len(), 5);
    let mut exact = 0;
    for p in &picks {
        let Some(buffer) = p["buffer_depth"].as_f64() else {
            continue;
        };
        let point = &p["point"];
        assert!(point.is_object(), "a covered pixel picks a point: {p}");
        if point["drawn_at"] == p["pixel"] {
            let d = f(&point["view_depth"]);
            assert!((d - buffer).abs() <= 1e-5 * buffer, "{p}");
            exact += 1;
        }
    }
    assert!(
        exact >= 4,
        "{exact} of 5 picks returned the drawn point: {stdout}"
    );
}

#[test]
fn a_distance_in_a_utm_sized_file_is_measured_to_a_millionth() {
    let dir = tmp_dir("utm");
    // A 100 m ground grid at UTM-sized coordinates and two points standing above it.
    let (x0, y0) = (512_300.0, 4_123_400.0);
    let mut points = Vec::new();
    for i in 0..=40 {
        for j in 0..=40 {
            points.push([x0 + 2.5 * f64::from(i), y0 + 2.5 * f64::from(j), 250.0]);
        }
    }
    let a = [512_345.678, 4_123_456.789, 262.5];
    let b = [512_380.123, 4_123_421.987, 251.25];
    points.push(a);
    points.push(b);
    let ply = dir.join("utm.ply");
    write_ply(&ply, &points, None);
    let camera = [
        "--eye",
        "512350,4123440,400",
        "--target",
        "512350,4123450,250",
        "--up",
        "z",
        "--k",
        "0",
    ];
    let locate = format!(
        "frames 1\nlocate {} {} {}\nlocate {} {} {}\n",
        a[0], a[1], a[2], b[0], b[1], b[2]
    );
    let located = records(&run(&dir, &ply, &locate, &camera), "locate");
    let px = |k: usize| (&located[k]["pixel"][0], &located[k]["pixel"][1]);
    let ((ax, ay), (bx, by)) = (px(0), px(1));
    let script = format!(
        "frames 2\nmeasure distance {ax} {ay} {bx} {by}\nmeasure height {ax} {ay} {bx} {by}\n\
         size 640x560\nscreenshot bar.png\n"
    );
    let mut colored = camera.to_vec();
    colored.extend(["--color-by", "elevation"]);
    let stdout = run(&dir, &ply, &script, &colored);
    // The elevation ramp's scale bar, bottom left (below the stats panel in a taller window):
    // the ramp's start and end colours.
    let shot = image::open(dir.join("bar.png")).expect("png").to_rgb8();
    let line = surfel::overlay::atlas().expect("atlas").line_height;
    let margin = surfel::overlay::MARGIN;
    let bottom = 560.0 - margin - (line + 2.0 * surfel::overlay::PADDING) - 4.0;
    let y = (bottom - 6.0) as u32;
    for (x, t) in [(margin + 1.0, 0.0), (margin + 254.0, 1.0)] {
        let got = shot.get_pixel(x as u32, y).0;
        let want = surfel::color::ramp(t);
        let close = got.iter().zip(want).all(|(g, w)| g.abs_diff(w) <= 12);
        assert!(close, "bar at {x}: {got:?} vs ramp({t}) {want:?}");
    }
    let m = records(&stdout, "measure");
    assert_eq!(m.len(), 2, "{stdout}");
    let truth = |p: [f64; 3]| glam::DVec3::from(p);
    let d = truth(b) - truth(a);
    for (k, expected) in [(0, a), (1, b)] {
        let p = &m[0]["picks"][k]["point"]["position"];
        for axis in 0..3 {
            assert!(
                (f(&p[axis]) - expected[axis]).abs() < 1e-5,
                "{p} vs {expected:?}"
            );
        }
    }
    let rel = |got: f64, want: f64| ((got - want) / want).abs();
    assert!(rel(f(&m[0]["distance"]), d.length()) < 1e-6, "{}", m[0]);
    assert!(rel(f(&m[0]["horizontal"]), d.truncate().length()) < 1e-6);
    assert!(rel(f(&m[0]["vertical"]), d.z.abs()) < 1e-6);
    assert!(
        rel(f(&m[1]["height"]), d.z) < 1e-6,
        "signed height: {}",
        m[1]
    );
}

/// The grid of the filter test: 20 x 20 points 0.1 apart in the z = 0 plane, class
/// (i + j) % 4, each drawn on its own pixel from z = 10.
fn grid() -> (Vec<[f64; 3]>, Vec<u8>) {
    let mut points = Vec::new();
    let mut classes = Vec::new();
    for i in 0..20 {
        for j in 0..20 {
            points.push([-0.95 + 0.1 * f64::from(i), -0.95 + 0.1 * f64::from(j), 0.0]);
            classes.push(((i + j) % 4) as u8);
        }
    }
    (points, classes)
}

#[test]
fn filtering_classes_and_clipping_boxes_change_the_projected_count_as_the_cpu_predicts() {
    let dir = tmp_dir("filter");
    let (points, classes) = grid();
    let ply = dir.join("grid.ply");
    write_ply(&ply, &points, Some(&classes));
    let inside = |p: &[f64; 3], c: [f64; 2], h: [f64; 2], yaw: f64| {
        let (s, co) = yaw.to_radians().sin_cos();
        let (dx, dy) = (p[0] - c[0], p[1] - c[1]);
        // Into the box's frame: rotate by -yaw.
        let (u, v) = (co * dx + s * dy, -s * dx + co * dy);
        u.abs() <= h[0] && v.abs() <= h[1]
    };
    let count = |keep: &dyn Fn(usize) -> bool| (0..points.len()).filter(|&i| keep(i)).count();
    let hide2 = count(&|i| classes[i] != 2);
    let only13 = count(&|i| classes[i] == 1 || classes[i] == 3);
    let aligned = count(&|i| inside(&points[i], [-0.2, 0.3], [0.42, 0.33], 0.0));
    let oriented = count(&|i| inside(&points[i], [0.1, -0.1], [0.61, 0.22], 30.0));
    let outside_hide2 =
        count(&|i| !inside(&points[i], [0.1, -0.1], [0.61, 0.22], 30.0) && classes[i] != 2);
    let script = "frames 2\ncount\nfilter hide 2\ncount\nfilter only 1 3\ncount\nfilter all\n\
                  clip box -0.62 -0.03 -1 0.22 0.63 1\ncount\n\
                  clip oriented 0.1 -0.1 0 0.61 0.22 1 30\ncount\n\
                  clip outside\nfilter hide 2\ncount\n\
                  key ctrl+1\nkey k\nfilter all\nclip off\ncount\nkey l\ncount\n\
                  key m\ncount\n";
    let stdout = run(
        &dir,
        &ply,
        script,
        &[
            "--eye",
            "0,0,10",
            "--target",
            "0,0,0",
            "--k",
            "0",
            "--camera-file",
            "cam.toml",
        ],
    );
    let counts = counts(&stdout);
    let expected = [
        400,
        hide2,
        only13,
        aligned,
        oriented,
        outside_hide2,
        400,
        outside_hide2,
        outside_hide2,
    ];
    assert_eq!(counts.len(), expected.len(), "{stdout}");
    for (k, ((pixels, kept), want)) in counts.iter().zip(expected).enumerate() {
        // Every point on its own pixel: the covered pixels are the projected points, for the
        // point pipeline and, after `key m`, the compute rasterizer.
        assert_eq!(
            (*pixels, *kept),
            (want as u64, want as u64),
            "count {k}: {stdout}"
        );
    }
    assert!(stdout.contains("method compute"), "{stdout}");
    assert!(aligned > 0 && oriented > 0 && aligned < 400 && oriented < 400);
    // The camera file keeps the box, the hidden classes and the bookmark.
    let saved = surfel::scene::scene_file::SceneFile::load(&dir.join("cam.toml")).expect("loads");
    assert_eq!(saved.hidden_classes, vec![2]);
    let clip = saved.clip.expect("clip box saved");
    assert_eq!(clip.keep, surfel::scene::clip::Keep::Outside);
    assert_eq!(clip.rotation, [30.0, 0.0, 0.0]);
    assert_eq!(saved.bookmarks.len(), 1);
    assert_eq!(saved.bookmarks[0].slot, 1);
}

#[test]
fn m_reaches_every_method_and_plus_bookmarks_and_the_budget_keys_act() {
    let dir = tmp_dir("every-method");
    let n = surfel::methods::METHODS.len();
    let mut script = String::from(
        "size 96x72\nkey Tab\nframes 1\ncount\nkey +\nkey +\ncount\nkey ctrl+2\n\
                                   screenshot a.png\norbit 100,10\nscreenshot b.png\nkey 2\n\
                                   screenshot c.png\nkey -\nkey -\ncount\nkey .\n",
    );
    script.push_str(&"key m\nframes 1\n".repeat(n));
    std::fs::write(dir.join("t.txt"), &script).expect("script");
    let o = view(
        &dir,
        "800x600",
        &data("stanford/bun_zipper.ply"),
        &["--script", "t.txt"],
    );
    assert!(o.status.success(), "viewer failed: {}", text(&o.stderr));
    let stdout = text(&o.stdout);
    for m in surfel::methods::METHODS {
        assert!(
            stdout.lines().any(|l| l == format!("method {}", m.name)),
            "M never reached {}: {stdout}",
            m.name
        );
    }
    // `+` twice: 1 -> 2 -> 3 pixel points cover more; `-` twice: back to 1 pixel.
    let covered: Vec<u64> = records(&stdout, "count")
        .iter()
        .map(|c| c["covered_pixels"].as_u64().expect("pixels"))
        .collect();
    assert_eq!(covered.len(), 3);
    assert!(
        covered[1] > covered[0] && covered[2] == covered[0],
        "{covered:?}"
    );
    assert!(stdout.contains("size 3") && stdout.contains("bookmark 2 stored"));
    assert!(stdout.contains("points has no budget"), "{stdout}");
    // Bookmark 2 brings the camera back (to float rounding of the orbit angles).
    let png = |name: &str| image::open(dir.join(name)).expect("png").to_rgb8();
    let differ = |a: &str, b: &str| {
        png(a)
            .pixels()
            .zip(png(b).pixels())
            .filter(|(p, q)| p != q)
            .count()
    };
    assert!(differ("a.png", "b.png") > 200, "the orbit moved the view");
    assert!(
        differ("a.png", "c.png") < 20,
        "{} pixels differ",
        differ("a.png", "c.png")
    );
}

#[test]
fn a_scripted_click_on_a_legend_line_toggles_its_class() {
    let dir = tmp_dir("legend-click");
    let (points, classes) = grid();
    let ply = dir.join("grid.ply");
    write_ply(&ply, &points, Some(&classes));
    // One click on every row of the stats panel (left edge, mid-line): the four legend lines
    // hide their classes, the other rows pick (away from the grid: nothing there).
    let line = surfel::overlay::atlas().expect("atlas").line_height;
    let top = surfel::overlay::MARGIN + surfel::overlay::PADDING;
    let x = top as i32 + 4;
    // The class stream is uploaded (and the graph rebuilt, which changes the HUD's lines
    // until the new graph is timed) the first time a class is hidden: before the clicks.
    let mut script = String::from("filter hide 0\nframes 5\nfilter all\nframes 5\ncount\n");
    let rows = 20;
    for row in 0..rows {
        let y = (top + (row as f32 + 0.5) * line) as i32;
        script.push_str(&format!("click {x} {y}\n"));
    }
    script.push_str("count\n");
    std::fs::write(dir.join("t.txt"), script).expect("script");
    let args = [
        "--size",
        "480x480",
        "--script",
        "t.txt",
        "--eye",
        "0,0,10",
        "--target",
        "0,0,0",
        "--k",
        "0",
        "--color-by",
        "classification",
    ];
    let o = view(&dir, "800x600", &ply, &args);
    assert!(o.status.success(), "viewer failed: {}", text(&o.stderr));
    let stdout = text(&o.stdout);
    let hidden: Vec<Value> = records(&stdout, "filter")
        .iter()
        .skip(2)
        .map(|f| f["hidden_classes"].clone())
        .collect();
    assert_eq!(
        hidden,
        [
            serde_json::json!([0]),
            serde_json::json!([0, 1]),
            serde_json::json!([0, 1, 2]),
            serde_json::json!([0, 1, 2, 3]),
        ],
        "{stdout}"
    );
    assert_eq!(records(&stdout, "pick").len(), rows - 4, "{stdout}");
    let counts = counts(&stdout);
    assert_eq!(counts, [(400, 400), (0, 0)], "{stdout}");
}

#[test]
fn the_clipping_box_outline_is_drawn_only_while_the_box_clips() {
    let dir = tmp_dir("clip-outline");
    let (points, classes) = grid();
    let ply = dir.join("grid.ply");
    write_ply(&ply, &points, Some(&classes));
    // The box's corner of the grid is drawn below and right of the HUD's panel.
    let script = "frames 2\nclip box 0.45 -0.95 -1 0.95 -0.45 1\nscreenshot on.png\nclip off\n\
                  screenshot off.png\nclip outside\nscreenshot outside.png\n";
    std::fs::write(dir.join("t.txt"), script).expect("script");
    let args = [
        "--size", "640x480", "--script", "t.txt", "--eye", "0,0,10", "--target", "0,0,0", "--k",
        "0",
    ];
    let o = view(&dir, "800x600", &ply, &args);
    assert!(o.status.success(), "viewer failed: {}", text(&o.stderr));
    // The outline's colour (the overlay draws it opaque); the grid is drawn in another.
    let outline = |name: &str| {
        image::open(dir.join(name))
            .expect("png")
            .to_rgb8()
            .pixels()
            .filter(|p| p.0 == [110, 200, 255])
            .count()
    };
    let (on, off, outside) = (
        outline("on.png"),
        outline("off.png"),
        outline("outside.png"),
    );
    assert!(on > 100, "{on} outline pixels");
    assert_eq!(off, 0, "the outline stays after `clip off`");
    assert_eq!(outside, on, "`clip outside` draws the remembered box again");
}
