//! Building a line model from a polygon mesh ([`convert`], in the spirit of thesis 000 §5.1.3).
//!
//! Corners are welded by exact position (OBJ files often repeat a position), then the mesh is
//! split into connected components (faces sharing a vertex). Each component is tried as:
//!
//! 1. **An open strip** (the thesis' leaf: a few faces in a row, single-sided): the faces form
//!    a path in which consecutive faces share exactly one edge (a *cross edge*; in a quad the
//!    two cross edges are opposite). It becomes a ribbon: the two ends (the mean of an end
//!    face's corners off its cross edge; a tip has radius 0), then the midpoint of each cross
//!    edge with half its length as radius. Normals are the faces' (mean of the two faces at a
//!    cross edge). The strip must be at least as long as it is wide.
//! 2. **Rings of quads** (a branch, or a leaf modelled as a flat closed box as in the
//!    Quaternius plants): a *band* is a closed loop of quads, each entered and left through
//!    opposite edges; its two *rails* (the other edges) are rings of vertices. A quad lies on
//!    two such loops (one per pair of opposite edges); in an all-quad closed mesh both may
//!    close, and the loop that goes *around* a thin tube has the shorter rails, so a band is
//!    a ring band when, in each of its quads, the other loop is open or has longer rails
//!    (ties, as on a cube, are not rings). Ring bands sharing a ring chain into a sequence of
//!    rings `r0 .. rk`; a ring shared by more than two bands (non-manifold) or a closed chain
//!    (a torus) is left as triangles. Each end of a chain may be closed by a **cap**: the
//!    faces reached from the end ring's outside without crossing a ring band, bounded by that
//!    ring alone, with at most twice as many faces and no more vertices off the ring than the
//!    ring has (a pyramid tip, a flat polygon). A cap's faces are converted too, and when it
//!    has vertices off the ring their mean is an extra end vertex: the tip, radius 0 when it
//!    is one vertex, else the largest distance from the mean to them.
//!
//!    Per ring: the centre is the mean of its vertices; the tangent is the normalized mean of
//!    the directions of the adjacent centre-line edges. The ring's vertices, projected on the
//!    plane across the tangent, give a width (extent along the principal axis) and a
//!    thickness (across it). A chain whose median thickness / width is below
//!    [`FLAT_RATIO`] is a **ribbon**: radius half the width, normal across the width (signs
//!    made to agree along the polyline). Otherwise it is a **tube**: radius the largest
//!    distance from the centre to the ring's vertices, direction the tangent; a tube whose
//!    largest radius exceeds [`THICK_RATIO`] times its length is thick (a trunk) and stays
//!    triangles, as the thesis keeps its apple tree's trunk; a ribbon shorter than it is wide
//!    stays triangles too. A polyline takes the colour of its first face.
//! 3. Anything else stays **triangles** (fan-triangulated), as do the faces of a component
//!    that no chain or cap took (branch junctions, the ends of non-manifold parts). No face is
//!    dropped: [`LineStats`] accounts for every input face.
//!
//! Limits: triangulated strips are not re-paired into quads (a diagonal becomes a cross edge
//! with too large a radius, or the strip is not recognised); tubes must be made of quads; a
//! branching tube breaks at each junction, whose faces stay triangles; the ring test compares
//! rail lengths, so a tube shorter than its circumference whose quads also close lengthwise
//! (like a cube) is not a ring; a loop of quads that crosses itself is traced again from each
//! of its quads (time grows with its length squared). The conversion is deterministic: same
//! mesh, same output.

use std::collections::HashMap;

use glam::Vec3;

use super::{LineKind, LineModel, LineStats, LineVertex, Polyline};
use crate::scene::cloud::{Cloud, LoadStats};
use crate::scene::obj::PolygonMesh;

/// A chain of rings is a ribbon when its median thickness / width is below this. Round rings
/// measure about 0.6 to 1 (the branches of `CommonTree_Dead_1.obj`: medians 0.67 to 1), the
/// folded fronds of `PalmTree_1.obj` 0.28 to 0.48 and the strap leaves of `Plant_3.obj` 0.16.
pub const FLAT_RATIO: f32 = 0.55;

/// A tube whose largest radius exceeds this times its length stays triangles.
pub const THICK_RATIO: f32 = 0.2;

/// The welded mesh and its edge table.
struct Mesh<'a> {
    positions: Vec<Vec3>,
    /// Polygons over welded vertices.
    faces: Vec<Vec<u32>>,
    colors: &'a [[u8; 4]],
    /// Faces on each edge `(low, high)`.
    edges: HashMap<(u32, u32), Vec<u32>>,
}

fn edge(a: u32, b: u32) -> (u32, u32) {
    (a.min(b), a.max(b))
}

impl Mesh<'_> {
    fn new(input: &PolygonMesh) -> Mesh<'_> {
        let mut welded: HashMap<[u32; 3], u32> = HashMap::new();
        let mut positions = Vec::new();
        let mut index = vec![u32::MAX; input.positions.len()];
        let faces: Vec<Vec<u32>> = input
            .polygons
            .iter()
            .map(|poly| {
                poly.iter()
                    .map(|&i| {
                        let slot = &mut index[i as usize];
                        if *slot == u32::MAX {
                            // +0.0 + -0.0 is +0.0: both zeros weld together.
                            let p = input.positions[i as usize] + Vec3::ZERO;
                            let key = p.to_array().map(f32::to_bits);
                            *slot = *welded.entry(key).or_insert_with(|| {
                                positions.push(p);
                                positions.len() as u32 - 1
                            });
                        }
                        *slot
                    })
                    .collect()
            })
            .collect();
        let mut edges: HashMap<(u32, u32), Vec<u32>> = HashMap::new();
        for (f, poly) in faces.iter().enumerate() {
            for k in 0..poly.len() {
                let e = edge(poly[k], poly[(k + 1) % poly.len()]);
                if e.0 != e.1 {
                    edges.entry(e).or_default().push(f as u32);
                }
            }
        }
        Mesh {
            positions,
            faces,
            colors: &input.colors,
            edges,
        }
    }

    fn p(&self, v: u32) -> Vec3 {
        self.positions[v as usize]
    }

    /// Whether a face's corners are distinct (else it is never converted).
    fn simple(&self, f: u32) -> bool {
        let poly = &self.faces[f as usize];
        (0..poly.len()).all(|i| !poly[i + 1..].contains(&poly[i]))
    }

    fn is_quad(&self, f: u32) -> bool {
        self.faces[f as usize].len() == 4 && self.simple(f)
    }

    /// Edge `k` of face `f`.
    fn face_edge(&self, f: u32, k: usize) -> (u32, u32) {
        let poly = &self.faces[f as usize];
        edge(poly[k % poly.len()], poly[(k + 1) % poly.len()])
    }

    /// The one other face on edge `e`, when exactly two faces share it.
    fn across(&self, e: (u32, u32), f: u32) -> Option<u32> {
        match self.edges.get(&e).map(Vec::as_slice) {
            Some(&[a, b]) if a == f => Some(b),
            Some(&[a, b]) if b == f => Some(a),
            _ => None,
        }
    }

    /// Newell's normal of a face (unit, or zero when degenerate).
    fn normal(&self, f: u32) -> Vec3 {
        let poly = &self.faces[f as usize];
        let mut n = Vec3::ZERO;
        for k in 0..poly.len() {
            let (a, b) = (self.p(poly[k]), self.p(poly[(k + 1) % poly.len()]));
            n += (a - b).cross(a + b) * 0.5;
        }
        n.normalize_or_zero()
    }

    /// Connected components (faces sharing a vertex), each a sorted face list, in the order of
    /// their first face.
    fn components(&self) -> Vec<Vec<u32>> {
        let mut parent: Vec<u32> = (0..self.positions.len() as u32).collect();
        fn find(parent: &mut [u32], mut x: u32) -> u32 {
            while parent[x as usize] != x {
                let up = parent[parent[x as usize] as usize];
                parent[x as usize] = up;
                x = up;
            }
            x
        }
        for poly in &self.faces {
            let a = find(&mut parent, poly[0]);
            for &v in &poly[1..] {
                let b = find(&mut parent, v);
                parent[b as usize] = a;
            }
        }
        let mut slot: HashMap<u32, usize> = HashMap::new();
        let mut components: Vec<Vec<u32>> = Vec::new();
        for (f, poly) in self.faces.iter().enumerate() {
            let root = find(&mut parent, poly[0]);
            let next = components.len();
            let i = *slot.entry(root).or_insert(next);
            if i == next {
                components.push(Vec::new());
            }
            components[i].push(f as u32);
        }
        components
    }
}

/// Converts a polygon mesh into ribbons, tubes and kept triangles (see the module
/// documentation). Pure and deterministic.
pub fn convert(input: &PolygonMesh) -> LineModel {
    let mesh = Mesh::new(input);
    let components = mesh.components();
    let mut converted = vec![false; mesh.faces.len()];
    let mut polylines = Vec::new();
    for component in &components {
        if let Some(ribbon) = strip(&mesh, component) {
            for &f in component {
                converted[f as usize] = true;
            }
            polylines.push(ribbon);
            continue;
        }
        for (polyline, faces) in chains(&mesh, component) {
            for f in faces {
                converted[f as usize] = true;
            }
            polylines.push(polyline);
        }
    }
    let triangles = kept_triangles(&mesh, &converted);
    let faces_converted = converted.iter().filter(|&&c| c).count();
    let input_vertices = mesh.positions.len();
    let faces_kept = mesh.faces.len() - faces_converted;
    let stats = LineStats {
        components: components.len(),
        input_vertices,
        faces_converted,
        faces_kept,
        ..LineStats::count(&polylines, &triangles)
    };
    LineModel {
        polylines,
        triangles,
        stats,
    }
}

/// The faces not converted, fan-triangulated, with their own vertices (area-weighted normals
/// of the kept faces; a vertex's colour is its first kept face's).
fn kept_triangles(mesh: &Mesh, converted: &[bool]) -> Cloud {
    let mut index: HashMap<u32, u32> = HashMap::new();
    let mut positions = Vec::new();
    let mut colors = Vec::new();
    let mut faces = Vec::new();
    for (f, poly) in mesh.faces.iter().enumerate() {
        if converted[f] {
            continue;
        }
        let corners: Vec<u32> = poly
            .iter()
            .map(|&v| {
                *index.entry(v).or_insert_with(|| {
                    positions.push(mesh.p(v));
                    colors.push(mesh.colors[f]);
                    positions.len() as u32 - 1
                })
            })
            .collect();
        for k in 2..corners.len() {
            faces.push([corners[0], corners[k - 1], corners[k]]);
        }
    }
    let mut normals = vec![Vec3::ZERO; positions.len()];
    for f in &faces {
        let [a, b, c] = f.map(|i| positions[i as usize]);
        let n = (b - a).cross(c - a);
        for &i in f {
            normals[i as usize] += n;
        }
    }
    let normals = normals
        .into_iter()
        .map(|n| {
            let n = n.normalize_or_zero();
            if n == Vec3::ZERO {
                Vec3::Z
            } else {
                n
            }
        })
        .collect();
    let records = positions.len();
    Cloud {
        positions,
        normals: Some(normals),
        colors: Some(colors),
        faces: Some(faces),
        stats: LoadStats {
            records,
            ..LoadStats::default()
        },
        ..Cloud::default()
    }
}

/// The mean of some vertices and the largest distance from it to them.
fn centre_and_reach(mesh: &Mesh, vertices: &[u32]) -> (Vec3, f32) {
    let centre = vertices.iter().map(|&v| mesh.p(v)).sum::<Vec3>() / vertices.len() as f32;
    let reach = vertices
        .iter()
        .map(|&v| mesh.p(v).distance(centre))
        .fold(0.0, f32::max);
    (centre, reach)
}

/// Step 1: a component whose faces form an open strip, as one ribbon.
fn strip(mesh: &Mesh, component: &[u32]) -> Option<Polyline> {
    if component.len() < 2 || !component.iter().all(|&f| mesh.simple(f)) {
        return None;
    }
    // Neighbours across shared edges: (face, edge index in this face).
    let mut links: HashMap<u32, Vec<(u32, usize)>> = HashMap::new();
    for &f in component {
        let mut list = Vec::new();
        for k in 0..mesh.faces[f as usize].len() {
            let e = mesh.face_edge(f, k);
            match mesh.edges[&e].len() {
                1 => {}
                2 => list.push((mesh.across(e, f)?, k)),
                _ => return None,
            }
        }
        let mut others: Vec<u32> = list.iter().map(|l| l.0).collect();
        others.sort_unstable();
        others.dedup();
        if list.len() > 2 || others.len() != list.len() {
            return None;
        }
        if let [(_, a), (_, b)] = list[..] {
            let n = mesh.faces[f as usize].len();
            // A quad is crossed through opposite edges; a larger polygon is not a strip face.
            if n > 4 || (n == 4 && (a + 2) % 4 != b) {
                return None;
            }
        }
        links.insert(f, list);
    }
    let start = *component.iter().find(|f| links[f].len() == 1)?;
    let mut order = vec![start];
    let mut cross = Vec::new();
    let mut previous = u32::MAX;
    let mut current = start;
    while let Some(&(next, k)) = links[&current].iter().find(|l| l.0 != previous) {
        cross.push(mesh.face_edge(current, k));
        order.push(next);
        previous = current;
        current = next;
        if order.len() > component.len() {
            return None;
        }
    }
    if order.len() != component.len() {
        return None;
    }
    // An end: the mean of the end face's corners off its cross edge.
    let end = |f: u32, e: (u32, u32)| -> (Vec3, f32) {
        let off: Vec<u32> = mesh.faces[f as usize]
            .iter()
            .copied()
            .filter(|&v| v != e.0 && v != e.1)
            .collect();
        centre_and_reach(mesh, &off)
    };
    let mut vertices = Vec::with_capacity(cross.len() + 2);
    let (p, r) = end(start, cross[0]);
    vertices.push(LineVertex {
        position: p,
        dir: mesh.normal(start),
        radius: r,
    });
    for (i, e) in cross.iter().enumerate() {
        let (a, b) = (mesh.p(e.0), mesh.p(e.1));
        let n = (mesh.normal(order[i]) + mesh.normal(order[i + 1])).normalize_or_zero();
        vertices.push(LineVertex {
            position: (a + b) * 0.5,
            dir: if n == Vec3::ZERO {
                mesh.normal(order[i])
            } else {
                n
            },
            radius: a.distance(b) * 0.5,
        });
    }
    let (p, r) = end(current, *cross.last()?);
    vertices.push(LineVertex {
        position: p,
        dir: mesh.normal(current),
        radius: r,
    });
    let length: f32 = vertices
        .windows(2)
        .map(|w| w[0].position.distance(w[1].position))
        .sum();
    let width = 2.0 * vertices.iter().map(|v| v.radius).fold(0.0, f32::max);
    (length >= width && length > 0.0).then(|| Polyline {
        kind: LineKind::Ribbon,
        vertices,
        color: mesh.colors[start as usize],
    })
}

/// A closed loop of quads.
struct Band {
    /// Quads in loop order, each with the index of the edge it is entered through (its axis is
    /// that index modulo 2).
    quads: Vec<(u32, usize)>,
    /// The two rails: vertex loops, `rails[0][i]` and `rails[1][i]` joined by the edge quad `i`
    /// is entered through.
    rails: [Vec<u32>; 2],
    /// Total length of both rails.
    rail_length: f32,
}

/// What tracing a loop of quads found.
enum Trace {
    /// A ring-shaped closed loop.
    Band(Band),
    /// No band: the states traced (quad, entry edge) reach the same dead end (a boundary, a
    /// non-quad, an edge with other than two faces) or make a closed loop that is not a band,
    /// so none of them lies on a band.
    Dead(Vec<(u32, usize)>),
    /// The loop meets a quad twice: no band through the start (the states after it may still
    /// close on their own).
    Crossing,
}

/// Traces the loop of quads from `q` entered through its edge `k`, leaving through `k + 2`.
fn trace_band(mesh: &Mesh, q: u32, k: usize) -> Trace {
    let mut quads = vec![(q, k)];
    let mut seen = std::collections::HashSet::from([q]);
    let (mut f, mut entry) = (q, k);
    loop {
        let exit = mesh.face_edge(f, entry + 2);
        let Some(next) = mesh.across(exit, f).filter(|&g| mesh.is_quad(g)) else {
            return Trace::Dead(quads);
        };
        let Some(k_next) = (0..4).find(|&j| mesh.face_edge(next, j) == exit) else {
            return Trace::Dead(quads);
        };
        if (next, k_next) == (q, k) {
            return match band_from_loop(mesh, quads.clone()) {
                Some(band) => Trace::Band(band),
                None => Trace::Dead(quads),
            };
        }
        if !seen.insert(next) {
            return Trace::Crossing;
        }
        quads.push((next, k_next));
        (f, entry) = (next, k_next);
    }
}

/// Splits the rungs (the edges the quads are entered through) of a closed loop of quads into
/// two rails; `None` unless they are two disjoint simple loops of at least 3 vertices.
fn band_from_loop(mesh: &Mesh, quads: Vec<(u32, usize)>) -> Option<Band> {
    let n = quads.len();
    if n < 3 {
        return None;
    }
    let rung = |i: usize| mesh.face_edge(quads[i].0, quads[i].1);
    let (a0, b0) = rung(0);
    let mut rails = [vec![a0], vec![b0]];
    for i in 1..n {
        let (a, b) = rung(i);
        // Quad i - 1 joins rung i - 1 to rung i by a rail edge from rails[0]'s last vertex.
        let last = rails[0][i - 1];
        let joined = |x: u32| (0..4).any(|j| mesh.face_edge(quads[i - 1].0, j) == edge(last, x));
        let (to0, to1) = if joined(a) {
            (a, b)
        } else if joined(b) {
            (b, a)
        } else {
            return None;
        };
        rails[0].push(to0);
        rails[1].push(to1);
    }
    let mut all: Vec<u32> = rails.iter().flatten().copied().collect();
    all.sort_unstable();
    all.dedup();
    if all.len() != 2 * n {
        return None;
    }
    let loop_length = |r: &[u32]| -> f32 {
        (0..r.len())
            .map(|i| mesh.p(r[i]).distance(mesh.p(r[(i + 1) % r.len()])))
            .sum()
    };
    let rail_length = loop_length(&rails[0]) + loop_length(&rails[1]);
    Some(Band {
        quads,
        rails,
        rail_length,
    })
}

/// A ring of vertices in a chain.
struct Ring {
    vertices: Vec<u32>,
    /// Ring bands on this ring.
    bands: Vec<usize>,
}

/// Step 2: ring bands of a component chained into ribbons and tubes, each with the faces it
/// converts (its bands' quads and its caps).
fn chains(mesh: &Mesh, component: &[u32]) -> Vec<(Polyline, Vec<u32>)> {
    // Both loops through every quad; `loop_of[(q, axis)]` indexes `bands` (None: open).
    let mut bands: Vec<Band> = Vec::new();
    let mut loop_of: HashMap<(u32, usize), Option<usize>> = HashMap::new();
    for &q in component {
        if !mesh.is_quad(q) {
            continue;
        }
        for axis in 0..2 {
            if loop_of.contains_key(&(q, axis)) {
                continue;
            }
            match trace_band(mesh, q, axis) {
                Trace::Band(band) => {
                    for &(f, k) in &band.quads {
                        loop_of.insert((f, k % 2), Some(bands.len()));
                    }
                    bands.push(band);
                }
                Trace::Dead(states) => {
                    for (f, k) in states {
                        loop_of.insert((f, k % 2), None);
                    }
                }
                Trace::Crossing => {
                    loop_of.insert((q, axis), None);
                }
            }
        }
    }
    // Ring bands: every quad's other loop is open or has longer rails.
    let ring_band: Vec<bool> = bands
        .iter()
        .enumerate()
        .map(|(b, band)| {
            band.quads.iter().all(|&(q, _)| {
                let other = (0..2)
                    .filter_map(|axis| loop_of.get(&(q, axis)).copied().flatten())
                    .find(|&o| o != b);
                other.is_none_or(|o| bands[o].rail_length > band.rail_length)
            })
        })
        .collect();
    // Rings by their sorted vertices, in order of first use.
    let mut ring_of: HashMap<Vec<u32>, usize> = HashMap::new();
    let mut rings: Vec<Ring> = Vec::new();
    let mut band_rings: HashMap<usize, [usize; 2]> = HashMap::new();
    for (b, band) in bands.iter().enumerate() {
        if !ring_band[b] {
            continue;
        }
        let ids = [0, 1].map(|side| {
            let mut key = band.rails[side].clone();
            key.sort_unstable();
            let next = rings.len();
            let id = *ring_of.entry(key).or_insert(next);
            if id == next {
                rings.push(Ring {
                    vertices: band.rails[side].clone(),
                    bands: Vec::new(),
                });
            }
            rings[id].bands.push(b);
            id
        });
        band_rings.insert(b, ids);
    }
    // Chains from end rings (one band); rings with more than two bands break chains.
    let usable = |r: usize| rings[r].bands.len() <= 2;
    let mut used_band = vec![false; bands.len()];
    let mut in_chain = vec![false; mesh.faces.len()];
    let mut found: Vec<(Vec<usize>, Vec<usize>)> = Vec::new();
    for start in 0..rings.len() {
        if rings[start].bands.len() != 1 || !usable(start) || used_band[rings[start].bands[0]] {
            continue;
        }
        let (mut chain_rings, mut chain_bands) = (vec![start], Vec::new());
        let mut ring = start;
        let complete = loop {
            let Some(&b) = rings[ring].bands.iter().find(|&&b| !used_band[b]) else {
                break true;
            };
            used_band[b] = true;
            chain_bands.push(b);
            let [r0, r1] = band_rings[&b];
            ring = if r0 == ring { r1 } else { r0 };
            chain_rings.push(ring);
            if !usable(ring) {
                break false;
            }
        };
        if complete {
            for &b in &chain_bands {
                for &(q, _) in &bands[b].quads {
                    in_chain[q as usize] = true;
                }
            }
            found.push((chain_rings, chain_bands));
        }
    }
    let mut out = Vec::new();
    for (chain_rings, chain_bands) in found {
        let caps = [0, chain_rings.len() - 1]
            .map(|end| cap(mesh, &rings[chain_rings[end]].vertices, &in_chain));
        let ring_vertices: Vec<&[u32]> = chain_rings
            .iter()
            .map(|&r| rings[r].vertices.as_slice())
            .collect();
        let color = mesh.colors[bands[chain_bands[0]].quads[0].0 as usize];
        if let Some(polyline) = chain_polyline(mesh, &ring_vertices, &caps, color) {
            let mut faces: Vec<u32> = chain_bands
                .iter()
                .flat_map(|&b| bands[b].quads.iter().map(|q| q.0))
                .collect();
            for c in caps.iter().flatten() {
                faces.extend(&c.faces);
            }
            out.push((polyline, faces));
        }
    }
    out
}

/// The faces closing one end of a chain.
struct Cap {
    faces: Vec<u32>,
    /// The mean of the cap's vertices off the ring and the largest distance from it to them,
    /// when it has any.
    tip: Option<(Vec3, f32)>,
}

/// The cap beyond an end `ring` of a chain (see the module documentation), or `None` for an
/// open end or one joined to more than this ring.
fn cap(mesh: &Mesh, ring: &[u32], in_chain: &[bool]) -> Option<Cap> {
    let n = ring.len();
    let ring_edges: Vec<(u32, u32)> = (0..n).map(|i| edge(ring[i], ring[(i + 1) % n])).collect();
    let mut region: Vec<u32> = Vec::new();
    for e in &ring_edges {
        for &f in mesh.edges.get(e)? {
            if !in_chain[f as usize] && !region.contains(&f) {
                region.push(f);
            }
        }
    }
    let mut next = 0;
    while next < region.len() {
        let f = region[next];
        next += 1;
        for k in 0..mesh.faces[f as usize].len() {
            let e = mesh.face_edge(f, k);
            if ring_edges.contains(&e) || e.0 == e.1 {
                continue;
            }
            let faces = &mesh.edges[&e];
            if faces.len() < 2 {
                return None;
            }
            for &g in faces {
                if in_chain[g as usize] {
                    return None;
                }
                if !region.contains(&g) {
                    region.push(g);
                }
            }
        }
        if region.len() > 2 * n {
            return None;
        }
    }
    if region.is_empty() {
        return None;
    }
    let mut off: Vec<u32> = region
        .iter()
        .flat_map(|&f| mesh.faces[f as usize].iter().copied())
        .filter(|v| !ring.contains(v))
        .collect();
    off.sort_unstable();
    off.dedup();
    if off.len() > n {
        return None;
    }
    Some(Cap {
        faces: region,
        tip: (!off.is_empty()).then(|| centre_and_reach(mesh, &off)),
    })
}

/// Width, thickness and the unit direction across the width of a ring's vertices projected on
/// the plane through `centre` across the unit `tangent`.
fn cross_section(mesh: &Mesh, ring: &[u32], centre: Vec3, tangent: Vec3) -> (f32, f32, Vec3) {
    let (u, w) = tangent.any_orthonormal_pair();
    let offsets: Vec<(f32, f32)> = ring
        .iter()
        .map(|&v| {
            let d = mesh.p(v) - centre;
            (d.dot(u), d.dot(w))
        })
        .collect();
    let (mut suu, mut suw, mut sww) = (0.0f32, 0.0f32, 0.0f32);
    for &(a, b) in &offsets {
        suu += a * a;
        suw += a * b;
        sww += b * b;
    }
    let angle = 0.5 * (2.0 * suw).atan2(suu - sww);
    let major = u * angle.cos() + w * angle.sin();
    let minor = tangent.cross(major).normalize_or_zero();
    let extent = |axis: Vec3| {
        let (lo, hi) = ring.iter().fold((f32::MAX, f32::MIN), |(lo, hi), &v| {
            let x = (mesh.p(v) - centre).dot(axis);
            (lo.min(x), hi.max(x))
        });
        hi - lo
    };
    (extent(major), extent(minor), minor)
}

/// Unit tangents of a polyline through `points`: the normalized mean of the directions of the
/// adjacent edges (`None` when an edge has zero length).
fn tangents(points: &[Vec3]) -> Option<Vec<Vec3>> {
    let dirs: Vec<Vec3> = points
        .windows(2)
        .map(|w| (w[1] - w[0]).try_normalize())
        .collect::<Option<_>>()?;
    (0..points.len())
        .map(|i| {
            let before = if i > 0 { dirs[i - 1] } else { Vec3::ZERO };
            let after = dirs.get(i).copied().unwrap_or(Vec3::ZERO);
            (before + after)
                .try_normalize()
                .or_else(|| after.try_normalize())
        })
        .collect()
}

/// The ribbon or tube through a chain's rings and caps; `None` for a thick tube, a ribbon
/// shorter than it is wide, or degenerate geometry.
fn chain_polyline(
    mesh: &Mesh,
    rings: &[&[u32]],
    caps: &[Option<Cap>; 2],
    color: [u8; 4],
) -> Option<Polyline> {
    let sections: Vec<(Vec3, f32)> = rings.iter().map(|r| centre_and_reach(mesh, r)).collect();
    // Tips: a cap's off-ring vertices, unless they lie at the end ring's centre.
    let tip = |end: usize, cap: &Option<Cap>| {
        let (centre, reach) = sections[end];
        cap.as_ref()
            .and_then(|c| c.tip)
            .filter(|(p, _)| p.distance(centre) > 0.05 * reach)
    };
    let first = tip(0, &caps[0]);
    let last = tip(sections.len() - 1, &caps[1]);
    let mut points: Vec<Vec3> = first.iter().map(|t| t.0).collect();
    points.extend(sections.iter().map(|s| s.0));
    points.extend(last.iter().map(|t| t.0));
    let tangent = tangents(&points)?;
    let offset = usize::from(first.is_some());
    let length: f32 = points.windows(2).map(|w| w[0].distance(w[1])).sum();
    let shapes: Vec<(f32, f32, Vec3)> = rings
        .iter()
        .enumerate()
        .map(|(i, r)| cross_section(mesh, r, sections[i].0, tangent[i + offset]))
        .collect();
    let mut flatness: Vec<f32> = shapes
        .iter()
        .map(
            |&(width, thickness, _)| {
                if width > 0.0 {
                    thickness / width
                } else {
                    1.0
                }
            },
        )
        .collect();
    flatness.sort_by(f32::total_cmp);
    let ribbon = flatness[flatness.len() / 2] < FLAT_RATIO;
    let mut middle: Vec<LineVertex> = Vec::with_capacity(rings.len());
    for (i, &(centre, reach)) in sections.iter().enumerate() {
        let (width, _, across) = shapes[i];
        middle.push(if ribbon {
            let previous = middle.last().map_or(across, |v| v.dir);
            LineVertex {
                position: centre,
                dir: if across.dot(previous) < 0.0 {
                    -across
                } else {
                    across
                },
                radius: width * 0.5,
            }
        } else {
            LineVertex {
                position: centre,
                dir: tangent[i + offset],
                radius: reach,
            }
        });
    }
    let end_vertex = |(position, radius): (Vec3, f32), next: &LineVertex, t: Vec3| LineVertex {
        position,
        dir: if ribbon { next.dir } else { t },
        radius,
    };
    let mut vertices = Vec::with_capacity(points.len());
    if let Some(t) = first {
        vertices.push(end_vertex(t, &middle[0], tangent[0]));
    }
    vertices.extend_from_slice(&middle);
    if let Some(t) = last {
        vertices.push(end_vertex(
            t,
            &middle[middle.len() - 1],
            tangent[points.len() - 1],
        ));
    }
    let widest = vertices.iter().map(|v| v.radius).fold(0.0, f32::max);
    let keep = if ribbon {
        length >= 2.0 * widest
    } else {
        widest <= THICK_RATIO * length
    };
    keep.then_some(Polyline {
        kind: if ribbon {
            LineKind::Ribbon
        } else {
            LineKind::Tube
        },
        vertices,
        color,
    })
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;

    const COLOR: [u8; 4] = [10, 200, 30, 255];

    fn mesh(positions: Vec<Vec3>, polygons: Vec<Vec<u32>>) -> PolygonMesh {
        PolygonMesh {
            colors: vec![COLOR; polygons.len()],
            positions,
            polygons,
            uncolored: 0,
        }
    }

    /// An open strip along +x in the z = 0 plane: a triangle tip at x = 0, cross edges at
    /// x = 1..=widths.len() with the given widths, a triangle tip at the end.
    fn strip_leaf(widths: &[f32]) -> PolygonMesh {
        let m = widths.len() as u32;
        let mut p = vec![Vec3::ZERO];
        for (i, w) in widths.iter().enumerate() {
            let x = i as f32 + 1.0;
            p.push(Vec3::new(x, -w / 2.0, 0.0));
            p.push(Vec3::new(x, w / 2.0, 0.0));
        }
        p.push(Vec3::new(m as f32 + 1.0, 0.0, 0.0));
        let (a, b) = (|i: u32| 2 * i - 1, |i: u32| 2 * i);
        let mut f = vec![vec![0, a(1), b(1)]];
        for i in 1..m {
            f.push(vec![a(i), a(i + 1), b(i + 1), b(i)]);
        }
        f.push(vec![a(m), 2 * m + 1, b(m)]);
        mesh(p, f)
    }

    #[derive(Clone, Copy)]
    enum End {
        Open,
        Flat,
        Tip(f32),
    }

    /// A tube along +y with `rings` elliptic rings of `around` vertices (half axes `rx`, `rz`)
    /// from y = 0 to `length`, joined by quads, its ends closed as asked.
    fn tube(rx: f32, rz: f32, length: f32, around: u32, rings: u32, ends: [End; 2]) -> PolygonMesh {
        let mut p = Vec::new();
        for j in 0..rings {
            let y = length * j as f32 / (rings - 1) as f32;
            for i in 0..around {
                let a = std::f32::consts::TAU * i as f32 / around as f32;
                p.push(Vec3::new(rx * a.cos(), y, rz * a.sin()));
            }
        }
        let at = |j: u32, i: u32| j * around + i % around;
        let mut f = Vec::new();
        for j in 0..rings - 1 {
            for i in 0..around {
                f.push(vec![at(j, i), at(j, i + 1), at(j + 1, i + 1), at(j + 1, i)]);
            }
        }
        for (end, ring, y) in [(ends[0], 0, 0.0), (ends[1], rings - 1, length)] {
            match end {
                End::Open => {}
                End::Flat => f.push((0..around).map(|i| at(ring, i)).collect()),
                End::Tip(h) => {
                    let apex = p.len() as u32;
                    p.push(Vec3::new(0.0, if y == 0.0 { -h } else { y + h }, 0.0));
                    for i in 0..around {
                        f.push(vec![at(ring, i), at(ring, i + 1), apex]);
                    }
                }
            }
        }
        mesh(p, f)
    }

    fn faces_accounted(input: &PolygonMesh, model: &LineModel) {
        let s = &model.stats;
        assert_eq!(s.faces_converted + s.faces_kept, input.polygons.len());
        assert_eq!(s.components, 1);
        assert_eq!(
            model.triangles.faces.as_ref().map_or(0, Vec::len),
            s.triangles
        );
    }

    #[test]
    fn an_open_strip_leaf_is_one_ribbon_with_tips_and_half_widths() {
        let input = strip_leaf(&[0.4, 0.6, 0.2]);
        let model = convert(&input);
        faces_accounted(&input, &model);
        assert_eq!(model.stats.faces_kept, 0);
        assert_eq!(model.polylines.len(), 1);
        let ribbon = &model.polylines[0];
        assert_eq!(ribbon.kind, LineKind::Ribbon);
        assert_eq!(ribbon.color, COLOR);
        let expected = [(0.0, 0.0), (1.0, 0.2), (2.0, 0.3), (3.0, 0.1), (4.0, 0.0)];
        assert_eq!(ribbon.vertices.len(), expected.len());
        for (v, (x, r)) in ribbon.vertices.iter().zip(expected) {
            assert!(v.position.distance(Vec3::new(x, 0.0, 0.0)) < 1e-6, "{v:?}");
            assert!((v.radius - r).abs() < 1e-6, "{v:?}");
            assert!((v.dir.z.abs() - 1.0).abs() < 1e-6, "{v:?}");
        }
        assert_eq!(model.stats.ribbons.segments, 4);
        assert_eq!(model.stats.output_vertices(), 5);
        assert_eq!(model.stats.input_vertices, 8);
    }

    #[test]
    fn a_wide_short_strip_is_kept() {
        let input = strip_leaf(&[5.0]);
        let model = convert(&input);
        faces_accounted(&input, &model);
        assert!(model.polylines.is_empty());
        assert_eq!(model.stats.triangles, 2);
    }

    #[test]
    fn a_ring_cylinder_is_one_tube_on_its_axis() {
        let r = 0.25;
        let input = tube(r, r, 4.0, 8, 6, [End::Open, End::Open]);
        let model = convert(&input);
        faces_accounted(&input, &model);
        assert_eq!(model.stats.faces_kept, 0);
        assert_eq!(model.polylines.len(), 1);
        let t = &model.polylines[0];
        assert_eq!(t.kind, LineKind::Tube);
        assert_eq!(t.vertices.len(), 6);
        let mut ys: Vec<f32> = t.vertices.iter().map(|v| v.position.y).collect();
        ys.sort_by(f32::total_cmp);
        for (j, (v, y)) in t.vertices.iter().zip(ys).enumerate() {
            assert!((y - 0.8 * j as f32).abs() < 1e-5, "{y}");
            assert!(v.position.x.abs() < 1e-6 && v.position.z.abs() < 1e-6);
            assert!((v.radius - r).abs() < 1e-6, "{v:?}");
            assert!((v.dir.y.abs() - 1.0).abs() < 1e-6, "{v:?}");
        }
        assert_eq!(model.stats.tubes.segments, 5);
    }

    #[test]
    fn caps_are_absorbed_and_a_pointed_cap_adds_its_tip() {
        let input = tube(0.1, 0.1, 2.0, 6, 5, [End::Flat, End::Tip(0.3)]);
        let model = convert(&input);
        faces_accounted(&input, &model);
        assert_eq!(model.stats.faces_kept, 0, "{:?}", model.stats);
        let t = &model.polylines[0];
        assert_eq!(t.kind, LineKind::Tube);
        assert_eq!(t.vertices.len(), 6);
        let tip = t
            .vertices
            .iter()
            .find(|v| (v.position.y - 2.3).abs() < 1e-5)
            .expect("tip vertex");
        assert_eq!(tip.radius, 0.0);
    }

    #[test]
    fn a_flat_closed_leaf_is_a_ribbon_with_pointed_ends() {
        let input = tube(0.3, 0.02, 3.0, 4, 5, [End::Tip(0.5), End::Tip(0.5)]);
        let model = convert(&input);
        faces_accounted(&input, &model);
        assert_eq!(model.stats.faces_kept, 0);
        let leaf = &model.polylines[0];
        assert_eq!(leaf.kind, LineKind::Ribbon);
        assert_eq!(leaf.vertices.len(), 7);
        let radii: Vec<f32> = leaf.vertices.iter().map(|v| v.radius).collect();
        assert_eq!((radii[0], radii[6]), (0.0, 0.0));
        for v in &leaf.vertices {
            // Normal across the width: along z, and all on one side.
            assert!(v.dir.z > 0.99 || v.dir.z < -0.99, "{v:?}");
            assert!(v.dir.dot(leaf.vertices[0].dir) > 0.0);
        }
        for r in &radii[1..6] {
            assert!((r - 0.3).abs() < 1e-5, "{radii:?}");
        }
    }

    #[test]
    fn thick_cylinders_and_blobs_stay_triangles() {
        let thick = tube(1.0, 1.0, 1.0, 8, 3, [End::Flat, End::Flat]);
        let octahedron = mesh(
            vec![Vec3::X, -Vec3::X, Vec3::Y, -Vec3::Y, Vec3::Z, -Vec3::Z],
            vec![
                vec![0, 2, 4],
                vec![2, 1, 4],
                vec![1, 3, 4],
                vec![3, 0, 4],
                vec![2, 0, 5],
                vec![1, 2, 5],
                vec![3, 1, 5],
                vec![0, 3, 5],
            ],
        );
        let cube = mesh(
            (0..8)
                .map(|i| Vec3::new((i & 1) as f32, (i >> 1 & 1) as f32, (i >> 2) as f32))
                .collect(),
            vec![
                vec![0, 2, 3, 1],
                vec![4, 5, 7, 6],
                vec![0, 1, 5, 4],
                vec![2, 6, 7, 3],
                vec![0, 4, 6, 2],
                vec![1, 3, 7, 5],
            ],
        );
        for (input, triangles) in [(thick, 32 + 2 * 6), (octahedron, 8), (cube, 12)] {
            let model = convert(&input);
            faces_accounted(&input, &model);
            assert!(model.polylines.is_empty());
            assert_eq!(model.stats.faces_kept, input.polygons.len());
            assert_eq!(model.stats.triangles, triangles);
            assert_eq!(model.stats.triangle_vertices, input.positions.len());
            let normals = model.triangles.normals.as_ref().expect("normals");
            assert!(normals.iter().all(|n| (n.length() - 1.0).abs() < 1e-5));
        }
    }

    #[test]
    fn repeated_positions_are_welded_and_the_conversion_is_deterministic() {
        let mut input = strip_leaf(&[0.4, 0.6]);
        // The second triangle's corners repeated as new vertices at the same positions.
        let n = input.positions.len() as u32;
        let last = input.polygons.len() - 1;
        let corners = input.polygons[last].clone();
        for &c in &corners {
            input.positions.push(input.positions[c as usize]);
        }
        input.polygons[last] = vec![n, n + 1, n + 2];
        let model = convert(&input);
        assert_eq!(model.polylines.len(), 1);
        assert_eq!(model, convert(&input));
    }

    /// A strip leaf, a capped thin tube and a thick cylinder (kept as triangles), converted.
    pub(in crate::scene::lines) fn sample_model() -> LineModel {
        let mut input = strip_leaf(&[0.4, 0.6]);
        let offset = input.positions.len() as u32;
        for (i, polygon) in [
            tube(0.1, 0.1, 2.0, 6, 5, [End::Flat, End::Tip(0.3)]),
            tube(1.0, 1.0, 1.0, 8, 3, [End::Flat, End::Flat]),
        ]
        .into_iter()
        .enumerate()
        {
            let base = input.positions.len() as u32;
            let shift = Vec3::new(5.0 * (i as f32 + 1.0), 0.0, 0.0);
            input
                .positions
                .extend(polygon.positions.iter().map(|&p| p + shift));
            for poly in polygon.polygons {
                input.polygons.push(poly.iter().map(|v| v + base).collect());
                input.colors.push([i as u8, 1, 2, 255]);
            }
        }
        assert!(offset > 0);
        convert(&input)
    }
}
