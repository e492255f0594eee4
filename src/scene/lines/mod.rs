//! The line model for thin geometry (thesis 000 §5.1): ribbons and tubes as polylines, with the
//! parts of a polygon mesh that are not thin kept as triangles.
//!
//! * A **ribbon** is a polyline along the centre of a flat strip; each vertex carries the
//!   strip's normal there and half its width as radius (§5.1.1).
//! * A **tube** is a polyline through the centre of a thin curved cylinder; each vertex carries
//!   the local tangent and the tube's radius (§5.1.2).
//!
//! The model and its invariants are here; `convert.rs` builds it from a polygon mesh
//! ([`convert()`]) and `format.rs` reads and writes its PLY file ([`save`], [`load`]).

mod convert;
mod format;

use glam::Vec3;

use crate::scene::cloud::{Cloud, Lines};

pub use convert::{convert, FLAT_RATIO, THICK_RATIO};
pub use format::{is_line_model, load, parse, save, to_text, MAGIC_COMMENT};

/// One polyline vertex.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LineVertex {
    pub position: Vec3,
    /// The unit normal for a ribbon, the unit tangent for a tube.
    pub dir: Vec3,
    /// Half the ribbon's width, or the tube's radius.
    pub radius: f32,
}

/// What a polyline stands for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LineKind {
    Ribbon,
    Tube,
}

/// A ribbon or a tube.
#[derive(Clone, Debug, PartialEq)]
pub struct Polyline {
    pub kind: LineKind,
    /// At least 2.
    pub vertices: Vec<LineVertex>,
    /// RGBA8 (sRGB).
    pub color: [u8; 4],
}

/// Polylines, segments and vertices of one kind.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct KindStats {
    pub polylines: usize,
    pub segments: usize,
    pub vertices: usize,
}

impl KindStats {
    fn add(&mut self, p: &Polyline) {
        self.polylines += 1;
        self.vertices += p.vertices.len();
        self.segments += p.vertices.len() - 1;
    }
}

/// What a conversion did, and the sizes of a line model.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LineStats {
    /// Connected components of the input (0 for a model read from a file).
    pub components: usize,
    /// Distinct vertex positions the input's faces use (0 for a model read from a file).
    pub input_vertices: usize,
    /// Input faces (polygons) that became lines (0 for a model read from a file).
    pub faces_converted: usize,
    /// Input faces (polygons) kept as triangles (0 for a model read from a file).
    pub faces_kept: usize,
    pub ribbons: KindStats,
    pub tubes: KindStats,
    /// Triangles of the kept part.
    pub triangles: usize,
    /// Vertices of the kept part.
    pub triangle_vertices: usize,
}

impl LineStats {
    /// Polyline vertices plus the kept triangles' vertices.
    pub fn output_vertices(&self) -> usize {
        self.ribbons.vertices + self.tubes.vertices + self.triangle_vertices
    }

    fn count(polylines: &[Polyline], triangles: &Cloud) -> LineStats {
        let mut stats = LineStats {
            triangles: triangles.faces.as_ref().map_or(0, Vec::len),
            triangle_vertices: triangles.len(),
            ..LineStats::default()
        };
        for p in polylines {
            match p.kind {
                LineKind::Ribbon => stats.ribbons.add(p),
                LineKind::Tube => stats.tubes.add(p),
            }
        }
        stats
    }
}

/// Ribbons and tubes plus the triangles that were not converted.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LineModel {
    pub polylines: Vec<Polyline>,
    /// The kept part: positions, normals, colors and triangle faces.
    pub triangles: Cloud,
    pub stats: LineStats,
}

impl LineModel {
    /// The model as a renderable cloud: the polylines' vertices first (normal = the ribbon
    /// normal or tube tangent, radius = half width or tube radius, the polyline's color), their
    /// segments as [`Lines`], then the kept triangles (radius 0: triangles are not expanded).
    pub fn to_cloud(&self) -> Cloud {
        let mut cloud = Cloud {
            normals: Some(Vec::new()),
            radii: Some(Vec::new()),
            colors: Some(Vec::new()),
            lines: Some(Lines::default()),
            ..Cloud::default()
        };
        let (normals, radii, colors) = (
            cloud.normals.as_mut().expect("set"),
            cloud.radii.as_mut().expect("set"),
            cloud.colors.as_mut().expect("set"),
        );
        let lines = cloud.lines.as_mut().expect("set");
        for p in &self.polylines {
            let first = cloud.positions.len() as u32;
            for v in &p.vertices {
                cloud.positions.push(v.position);
                normals.push(v.dir);
                radii.push(v.radius);
                colors.push(p.color);
            }
            let segments = (0..p.vertices.len() as u32 - 1).map(|k| [first + k, first + k + 1]);
            match p.kind {
                LineKind::Ribbon => lines.ribbons.extend(segments),
                LineKind::Tube => lines.tubes.extend(segments),
            }
        }
        let t = &self.triangles;
        let first = cloud.positions.len() as u32;
        cloud.positions.extend(&t.positions);
        normals.extend(t.normals.clone().unwrap_or_else(|| vec![Vec3::Z; t.len()]));
        radii.extend(std::iter::repeat_n(0.0, t.len()));
        colors.extend(t.colors.clone().unwrap_or_else(|| vec![[255; 4]; t.len()]));
        cloud.faces = t
            .faces
            .as_ref()
            .map(|f| f.iter().map(|tri| tri.map(|i| i + first)).collect());
        cloud.stats.records = cloud.positions.len();
        cloud
    }
}
