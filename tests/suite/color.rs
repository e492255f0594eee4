//! Color by attribute and true colors: exact colors read back from frames rendered on lavapipe
//! with validation (and synchronization validation) on.

use crate::common;

use std::collections::BTreeMap;
use std::sync::Arc;

use glam::Vec3;
use surfel::color::{self, class_color, return_color, rgb8, Coloring};
use surfel::gpu_scene::{upload, UploadOptions};
use surfel::layout::*;
use surfel::render::{Renderer, RendererOptions, View};
use surfel::scene::{Camera, Cloud, Light, Scalar, Up};

/// A `n` x `n` grid over [-1, 1]² seen from +z, in three plateaus along x: the left third at
/// z = 0, the middle at z = 0.5, the right at z = 1; normals +z. Each third has its value
/// of a scalar field `name` (after a field `other`) and its color.
fn plateaus(n: usize, name: &str, values: [f32; 3], colors: [[u8; 3]; 3]) -> Cloud {
    let mut positions = Vec::new();
    let mut scalar = Vec::new();
    let mut rgb = Vec::new();
    for j in 0..n {
        for i in 0..n {
            let t = |k: usize| -1.0 + 2.0 * (k as f32 + 0.5) / n as f32;
            let third = (3 * i / n).min(2);
            positions.push(Vec3::new(t(i), t(j), 0.5 * third as f32));
            scalar.push(values[third]);
            let [r, g, b] = colors[third];
            rgb.push([r, g, b, 255]);
        }
    }
    let count = positions.len();
    Cloud {
        normals: Some(vec![Vec3::Z; count]),
        radii: Some(vec![2.0 / n as f32; count]),
        colors: Some(rgb),
        scalars: vec![
            Scalar {
                name: "other".into(),
                values: vec![0.0; count],
            },
            Scalar {
                name: name.into(),
                values: scalar,
            },
        ],
        positions,
        up: Up::Z,
        ..Default::default()
    }
}

const GREYS: [[u8; 3]; 3] = [[90, 90, 90]; 3];

/// Counts of every covered pixel's color.
fn histogram(frame: &surfel::eval::Frame) -> BTreeMap<[u8; 3], usize> {
    let mut h = BTreeMap::new();
    for i in (0..frame.pixels()).filter(|&i| frame.covered(i)) {
        let [r, g, b, _] = frame.color[i];
        *h.entry([r, g, b]).or_insert(0) += 1;
    }
    h
}

/// Every covered pixel has one of `expected` (within `tolerance` per channel), and each of
/// them covers at least a tenth of the covered pixels.
fn assert_only(frame: &surfel::eval::Frame, expected: &[[u8; 3]], tolerance: u8, what: &str) {
    let h = histogram(frame);
    let total: usize = h.values().sum();
    assert!(total > 1000, "{what}: {total} covered pixels");
    let near = |a: [u8; 3], b: [u8; 3]| (0..3).all(|k| a[k].abs_diff(b[k]) <= tolerance);
    for (color, n) in &h {
        assert!(
            expected.iter().any(|e| near(*e, *color)),
            "{what}: {n} pixels of {color:?}, expected only {expected:?}"
        );
    }
    for e in expected {
        let n: usize = h
            .iter()
            .filter(|(c, _)| near(**c, *e))
            .map(|(_, n)| n)
            .sum();
        assert!(
            n * 10 >= total,
            "{what}: {e:?} covers {n} of {total} pixels"
        );
    }
}

const METHODS: [&str; 2] = ["points:size=3", "compute"];

fn select(cloud: &Cloud, name: &str) -> Coloring {
    color::select(cloud, name, Up::Z).expect("field")
}

#[test]
fn classification_uses_the_asprs_palette() {
    let cloud = plateaus(96, "classification", [2.0, 6.0, 40.0], GREYS);
    let coloring = select(&cloud, "classification");
    assert_eq!(
        coloring.scalar,
        Some(1),
        "only the selected field is uploaded"
    );
    for method in METHODS {
        let frame = common::render_colored(&cloud, method, 96, coloring);
        // Unlit: the palette colors exactly (ground, building, any other class).
        assert_eq!(class_color(2), rgb8(CLASS_COLOR_2));
        assert_only(
            &frame,
            &[class_color(2), class_color(6), rgb8(CLASS_COLOR_OTHER)],
            0,
            method,
        );
    }
}

#[test]
fn return_numbers_use_the_return_palette() {
    let cloud = plateaus(96, "return_number", [1.0, 2.0, 7.0], GREYS);
    let frame = common::render_colored(&cloud, "compute", 96, select(&cloud, "return"));
    assert_only(
        &frame,
        &[return_color(1), return_color(2), return_color(5)],
        0,
        "return",
    );
}

#[test]
fn elevation_ramp_runs_from_the_lowest_to_the_highest_point() {
    // Without normals the frame is unlit: the ramp's colors exactly.
    let cloud = Cloud {
        normals: None,
        ..plateaus(96, "x", [0.0; 3], GREYS)
    };
    let coloring = select(&cloud, "elevation");
    assert_eq!(coloring.range, [0.0, 1.0]);
    assert!(
        !coloring.unlit,
        "a surface color, lit where there are normals"
    );
    for method in METHODS {
        let frame = common::render_colored(&cloud, method, 96, coloring);
        // Lowest: the ramp's start; half way: its middle stop; highest: its end.
        assert_only(
            &frame,
            &[rgb8(RAMP_0), rgb8(RAMP_2), rgb8(RAMP_4)],
            0,
            method,
        );
    }
}

#[test]
fn scalars_and_intensity_span_their_robust_range() {
    let cloud = plateaus(96, "Deviation", [-5.0, 0.0, 5.0], GREYS);
    let frame = common::render_colored(&cloud, "compute", 96, select(&cloud, "Deviation"));
    assert_only(
        &frame,
        &[rgb8(RAMP_0), rgb8(RAMP_2), rgb8(RAMP_4)],
        0,
        "Deviation",
    );
    let cloud = plateaus(96, "intensity", [0.0, 50.0, 100.0], GREYS);
    let frame = common::render_colored(&cloud, "compute", 96, select(&cloud, "intensity"));
    // Grey ramp: 0, 0.5 (sRGB 127.5, either neighbour) and 1.
    assert_only(&frame, &[[0; 3], [128; 3], [255; 3]], 1, "intensity");
}

#[test]
fn normals_show_as_colors() {
    let cloud = plateaus(96, "x", [0.0; 3], GREYS);
    let frame = common::render_colored(&cloud, "compute", 96, select(&cloud, "normal"));
    // +z: (0.5, 0.5, 1) in sRGB.
    assert_only(&frame, &[[128, 128, 255]], 1, "normal");
}

/// The image centre (the middle plateau faces the headlight there).
fn centre(frame: &surfel::eval::Frame) -> [u8; 3] {
    let c = frame.color[(frame.height / 2 * frame.width + frame.width / 2) as usize];
    assert_eq!(c[3], 255, "centre covered");
    [c[0], c[1], c[2]]
}

#[test]
fn file_colors_stay_true_under_the_default_light() {
    for method in ["points:size=3", "compute", "compute-hq"] {
        let cloud = plateaus(
            96,
            "x",
            [0.0; 3],
            [[10, 200, 30], [200, 100, 50], [0, 0, 0]],
        );
        let lit = centre(&common::render_colored(
            &cloud,
            method,
            97,
            select(&cloud, "rgb"),
        ));
        assert!(
            lit.iter()
                .zip([200u8, 100, 50])
                .all(|(a, b)| a.abs_diff(b) <= 3),
            "{method}: 200,100,50 renders as {lit:?}"
        );
        let cloud = plateaus(96, "x", [0.0; 3], [[0, 0, 0]; 3]);
        let black = centre(&common::render_colored(
            &cloud,
            method,
            97,
            select(&cloud, "rgb"),
        ));
        assert!(
            black.iter().all(|&c| c <= 10),
            "{method}: black renders as {black:?}"
        );
        // The base color (linear 0.7, sRGB 218) keeps its value too.
        let none = centre(&common::render_colored(
            &cloud,
            method,
            97,
            select(&cloud, "none"),
        ));
        assert!(
            none.iter().all(|&c| c.abs_diff(218) <= 3),
            "{method}: none {none:?}"
        );
    }
}

#[test]
fn the_scalar_stream_swaps_in_place_of_a_fresh_upload() {
    let mut cloud = plateaus(96, "classification", [2.0, 6.0, 40.0], GREYS);
    cloud.scalars[0] = Scalar {
        name: "Deviation".into(),
        values: cloud.scalars[1].values.iter().map(|&c| -c).collect(),
    };
    let ctx = common::context();
    let (mut scene, mut info) = upload(
        &ctx,
        &cloud,
        &UploadOptions::colored(select(&cloud, "classification")),
    )
    .expect("upload");
    let config = surfel::methods::MethodConfig::parse("compute").expect("method");
    let view = View {
        camera: Camera::framing(info.centre, info.radius),
        lights: vec![Light::headlight()],
        use_color: true,
        time: 0.0,
    };
    let render = |scene: &surfel::gpu_scene::GpuScene, info| {
        let mut r = Renderer::new(
            &Arc::clone(&ctx),
            scene,
            info,
            &config,
            96,
            96,
            RendererOptions {
                readback: true,
                ..RendererOptions::default()
            },
        )
        .expect("renderer");
        r.render(&view, true).expect("frame").expect("readback")
    };
    let before = render(&scene, info);
    assert_only(
        &before,
        &[class_color(2), class_color(6), rgb8(CLASS_COLOR_OTHER)],
        0,
        "classification",
    );
    // Deviation: -2, -6, -40 over the robust range [-40, -2]: red, orange, blue.
    let coloring = select(&cloud, "Deviation");
    assert_eq!(coloring.scalar, Some(0));
    scene
        .streams
        .select_scalar(&ctx, &cloud, coloring.scalar, 4096)
        .expect("swap");
    assert_eq!(scene.streams.scalar, Some(0));
    info.coloring = coloring;
    let swapped = render(&scene, info);
    let fresh = common::render_colored(&cloud, "compute", 96, coloring);
    assert_eq!(swapped.color, fresh.color);
    assert_eq!(histogram(&swapped).len(), 3);
    // Back to no scalar stream at all.
    scene
        .streams
        .select_scalar(&ctx, &cloud, None, 4096)
        .expect("drop");
    assert!(scene
        .streams
        .segments
        .iter()
        .flatten()
        .all(|(s, _)| !matches!(s, surfel::point_streams::Stream::Scalar(_))));
    common::assert_clean(&ctx);
}

/// A `n` x `n` grid over [-1, 1]² in the z = 0 plane, two triangles per cell, normals +z, +y
/// up and no colors: seen from +z (`Camera::framing`), its elevation rises from the bottom row
/// of the image to the top one.
fn upright_plane(n: usize) -> Cloud {
    let t = |k: usize| -1.0 + 2.0 * k as f32 / (n - 1) as f32;
    let positions: Vec<Vec3> = (0..n * n)
        .map(|k| Vec3::new(t(k % n), t(k / n), 0.0))
        .collect();
    let at = |i: usize, j: usize| (j * n + i) as u32;
    let faces = (0..n - 1)
        .flat_map(|j| (0..n - 1).map(move |i| (i, j)))
        .flat_map(|(i, j)| {
            [
                [at(i, j), at(i + 1, j), at(i + 1, j + 1)],
                [at(i, j), at(i + 1, j + 1), at(i, j + 1)],
            ]
        })
        .collect();
    let count = positions.len();
    Cloud {
        normals: Some(vec![Vec3::Z; count]),
        radii: Some(vec![2.0 / (n - 1) as f32; count]),
        faces: Some(faces),
        positions,
        up: Up::Y,
        ..Default::default()
    }
}

/// sRGB bytes to linear.
fn linear(c: [u8; 3]) -> [f64; 3] {
    c.map(|v| {
        let v = f64::from(v) / 255.0;
        if v <= 0.04045 {
            v / 12.92
        } else {
            ((v + 0.055) / 1.055).powf(2.4)
        }
    })
}

/// The chromaticity (each linear channel over their sum) of the mean linear color of the
/// covered pixels in each of `BANDS` equal bands of the covered rows, top first, and of the
/// elevation ramp over the same pixels, a pixel's ramp position being its row's position
/// between the lowest covered row (0) and the highest (1).
const BANDS: usize = 4;
fn band_chromaticities(frame: &surfel::eval::Frame) -> [([f64; 3], [f64; 3]); BANDS] {
    let w = frame.width as usize;
    let rows: Vec<usize> = (0..frame.pixels())
        .filter(|&i| frame.covered(i))
        .map(|i| i / w)
        .collect();
    let (top, bottom) = (rows[0], rows[rows.len() - 1]);
    let span = (bottom - top + 1) as f64;
    let mut sums = [([0.0; 3], [0.0; 3]); BANDS];
    for i in (0..frame.pixels()).filter(|&i| frame.covered(i)) {
        let row = i / w;
        let band = ((row - top) * BANDS / (bottom - top + 1)).min(BANDS - 1);
        let [r, g, b, _] = frame.color[i];
        let expected = linear(color::ramp(((bottom - row) as f64 / (span - 1.0)) as f32));
        for (k, v) in linear([r, g, b]).into_iter().enumerate() {
            sums[band].0[k] += v;
            sums[band].1[k] += expected[k];
        }
    }
    sums.map(|(got, want)| {
        let chroma = |c: [f64; 3]| {
            let sum = c.iter().sum::<f64>().max(1e-9);
            c.map(|v| v / sum)
        };
        (chroma(got), chroma(want))
    })
}

#[test]
fn every_method_colors_a_cloud_without_colors_by_the_same_elevation_ramp() {
    let cloud = upright_plane(40);
    // The default field reads the file alone: elevation, whether or not a method estimates
    // normals (this cloud has them already).
    let field = color::default_field(&cloud);
    assert_eq!(field, "elevation");
    let coloring = color::select(&cloud, field, cloud.up).expect("elevation");
    let ctx = common::context();
    let mut checked = Vec::new();
    for method in surfel::methods::METHODS
        .iter()
        .filter(|m| m.unsupported(&ctx.caps).is_none())
    {
        let config = surfel::methods::MethodConfig::parse(method.name).expect("method");
        let options = config
            .method
            .upload_options(UploadOptions::colored(coloring));
        let (scene, info) = upload(&ctx, &cloud, &options).expect("upload");
        let camera = Camera::framing(info.centre, info.radius);
        let frame = common::two_frames(
            &ctx,
            &scene,
            info,
            method.name,
            48,
            RendererOptions::default(),
            camera,
        );
        let covered = (0..frame.pixels()).filter(|&i| frame.covered(i)).count();
        assert!(covered > 900, "{}: {covered} covered pixels", method.name);
        let bands = band_chromaticities(&frame);
        // The ramp runs from blue at the bottom to red at the top: the bands differ as it does
        // (grey would be a third in every channel of every band, 0.4 off), lit or not. Most
        // methods come within 0.04 of it; the level of detail draws this plane with its
        // coarsest samples (a plane has no perpendicular error), each the mean of up to 64
        // points, within 0.08.
        for (band, (got, want)) in bands.iter().enumerate() {
            assert!(
                (0..3).all(|k| (got[k] - want[k]).abs() < 0.12),
                "{}: band {band} (top first) has chromaticity {got:.3?}, the ramp {want:.3?}",
                method.name
            );
        }
        checked.push(method.name);
    }
    assert!(checked.len() >= 20, "methods run: {checked:?}");
}
