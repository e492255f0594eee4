//! `surfel convert-lines`: a polygon mesh to the line model (ribbons, tubes, kept triangles)
//! hybrid scenes draw.

use std::path::PathBuf;

use anyhow::{bail, Context as _, Result};
use clap::Args;

#[derive(Args, Debug)]
pub struct ConvertLinesArgs {
    /// Polygon mesh (obj; materials from its mtllib give the colours).
    pub mesh: PathBuf,
    /// Write the line model (ASCII PLY: vertices, polylines, kept triangles) to FILE.
    #[arg(long, value_name = "FILE")]
    pub out: Option<PathBuf>,
}

pub(super) fn convert_lines(a: ConvertLinesArgs) -> Result<()> {
    use crate::scene::lines;
    if crate::scene::format_extension(&a.mesh) != "obj" {
        bail!(
            "{}: expected an .obj mesh (polygons and materials)",
            a.mesh.display()
        );
    }
    let mesh = crate::scene::obj::load_polygons(&a.mesh)?;
    if mesh.polygons.is_empty() {
        bail!("{}: the mesh has no faces", a.mesh.display());
    }
    let model = lines::convert(&mesh);
    let s = &model.stats;
    println!("file              {}", a.mesh.display());
    println!("components        {}", s.components);
    println!(
        "faces             {} in: {} converted, {} kept",
        mesh.polygons.len(),
        s.faces_converted,
        s.faces_kept
    );
    for (name, k) in [("ribbons", s.ribbons), ("tubes", s.tubes)] {
        println!(
            "{name:<17} {} polylines, {} segments, {} vertices",
            k.polylines, k.segments, k.vertices
        );
    }
    println!(
        "triangles kept    {} triangles, {} vertices",
        s.triangles, s.triangle_vertices
    );
    println!(
        "vertices          {} in, {} out ({:.1} %)",
        s.input_vertices,
        s.output_vertices(),
        100.0 * s.output_vertices() as f64 / s.input_vertices.max(1) as f64
    );
    if mesh.uncolored > 0 {
        println!("no material       {} faces (grey)", mesh.uncolored);
    }
    if let Some(out) = &a.out {
        lines::save(out, &model).with_context(|| format!("{}: cannot write", out.display()))?;
        println!("written           {}", out.display());
    }
    Ok(())
}
