//! Consistent orientation of estimated normals. A PCA normal has no sign; this module gives
//! every estimated normal of a cloud one, by the first rule that applies ([`Rule`]):
//!
//! * **towards the scanner** when the file says where it stood (an E57 scan's pose, a PCD
//!   `VIEWPOINT`): a scanner only sees surfaces that face it;
//! * **up** for survey data (LAS, LAZ, COPC, text in projected coordinates): airborne and
//!   terrestrial LiDAR see the ground, roofs and canopy from above;
//! * **by propagation** otherwise: Hoppe et al. 1992, a minimum spanning tree over the
//!   k-nearest-neighbour graph weighted by `1 - |n_i · n_j|`, each point taking the sign of the
//!   neighbour it is reached from; each connected part's sign is then chosen so that most of
//!   it faces away from the cloud's centroid.
//!
//! The first two rules are trusted only where they are unambiguous: a point whose normal is
//! within [`SENSOR_ANCHOR`] of perpendicular to its line of sight, or within [`UP_ANCHOR`] of
//! horizontal (walls, cliffs, the sides of trees), is not oriented by the rule but reached by
//! the same propagation from the points that are (an anchored spanning forest, grown by
//! Prim's rule from every anchor at once). The tree is grown through a bucket queue of
//! [`LEVELS`] levels of `|n_i · n_j|` instead of a binary heap: the order differs only between
//! edges less than 1/64 apart in weight, and the walk is linear in the edges.

use glam::Vec3;
use rayon::prelude::*;

use super::camera::Up;
use super::cloud::{Cloud, Sensor};
use super::morton::morton_order;
use super::preprocess::centroid;

/// Neighbours per point kept for the propagation graph (the nearest of the k-NN search).
pub const GRAPH_K: usize = 6;

/// A point oriented towards the scanner must see it at least this far from edge-on
/// (`|n · d| ≥` this, `d` the unit direction to the scanner).
pub const SENSOR_ANCHOR: f32 = 0.1;

/// A point oriented up must have `|n · up|` at least this (within 60° of vertical).
pub const UP_ANCHOR: f32 = 0.5;

/// Priority levels of the propagation's bucket queue.
const LEVELS: usize = 64;

/// "No neighbour" in a graph row.
pub const NONE: u32 = u32::MAX;

/// How a cloud's estimated normals get their sign.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Rule {
    /// Towards the scanner of each point's scan.
    Sensor,
    /// Towards this up axis.
    Up(Up),
    /// Propagation over the neighbour graph, each part facing away from the centroid.
    Propagate,
}

impl Rule {
    /// The rule for `cloud`: its scanners when the file recorded them, up for survey data,
    /// else propagation.
    pub fn for_cloud(cloud: &Cloud) -> Rule {
        if cloud.sensors.iter().any(|s| s.position.is_finite()) {
            Rule::Sensor
        } else if cloud.survey {
            Rule::Up(cloud.up)
        } else {
            Rule::Propagate
        }
    }

    /// What `surfel info` says of the rule.
    pub fn describe(&self) -> String {
        match self {
            Rule::Sensor => format!(
                "towards the scanner (the file's scan positions), propagated where |n·d| < {SENSOR_ANCHOR}"
            ),
            Rule::Up(up) => format!(
                "up ({}), propagated over the k-NN graph where |n·up| < {UP_ANCHOR} (walls, slopes)",
                up.name()
            ),
            Rule::Propagate => {
                "propagated over the k-NN graph (Hoppe 1992 spanning tree), each part facing away from the centroid"
                    .to_string()
            }
        }
    }
}

/// The nearest neighbours of every point, [`GRAPH_K`] per row in input order, [`NONE`] where a
/// point has fewer.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Graph {
    pub rows: Vec<u32>,
}

impl Graph {
    /// An empty graph for `n` points.
    pub fn new(n: usize) -> Self {
        Graph {
            rows: vec![NONE; n * GRAPH_K],
        }
    }

    fn row(&self, i: usize) -> impl Iterator<Item = usize> + '_ {
        self.rows[i * GRAPH_K..(i + 1) * GRAPH_K]
            .iter()
            .take_while(|&&j| j != NONE)
            .map(|&j| j as usize)
    }
}

/// What [`orient`] did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Report {
    /// Points oriented by the rule itself.
    pub anchored: usize,
    /// Points oriented by propagation.
    pub propagated: usize,
    /// Parts of the graph without an anchor, each oriented by its own vote.
    pub parts: usize,
}

/// The scanner of point `i`: the last scan starting at or before it.
fn sensor_of(sensors: &[Sensor], i: usize) -> Option<Vec3> {
    let at = sensors.partition_point(|s| s.first <= i);
    at.checked_sub(1)
        .map(|a| sensors[a].position)
        .filter(|p| p.is_finite())
}

/// How much `n` at `p` agrees with the rule's reference direction, in [-1, 1] (0 without one).
fn prior(rule: Rule, sensors: &[Sensor], centre: Vec3, i: usize, p: Vec3, n: Vec3) -> f32 {
    let reference = match rule {
        Rule::Sensor => sensor_of(sensors, i).map_or(Vec3::ZERO, |s| s - p),
        Rule::Up(up) => up.vector(),
        Rule::Propagate => p - centre,
    };
    n.dot(reference.normalize_or_zero())
}

/// Orients `normals` (unit, any sign) of `cloud`'s points by `rule` over `graph`. Anchors are
/// oriented in parallel; the walk runs over the points still to orient and the anchors beside
/// them only, in Morton order, so that neighbours are near in memory.
pub fn orient(cloud: &Cloud, normals: &mut [Vec3], graph: &Graph, rule: Rule) -> Report {
    let positions = &cloud.positions;
    let n = positions.len();
    assert_eq!(normals.len(), n, "one normal per point");
    assert_eq!(graph.rows.len(), n * GRAPH_K, "one graph row per point");
    let centre = centroid(positions);
    let sensors = &cloud.sensors;
    let threshold = match rule {
        Rule::Sensor => SENSOR_ANCHOR,
        Rule::Up(_) => UP_ANCHOR,
        Rule::Propagate => f32::INFINITY,
    };
    let prior_of = |i: usize, normal: Vec3| prior(rule, sensors, centre, i, positions[i], normal);
    // Anchors take the rule's sign at once.
    let anchors: Vec<bool> = normals
        .par_iter_mut()
        .enumerate()
        .map(|(i, normal)| {
            let p = prior_of(i, *normal);
            if p < 0.0 {
                *normal = -*normal;
            }
            p.abs() >= threshold
        })
        .collect();
    let anchored = anchors.iter().filter(|&&a| a).count();
    if anchored == n {
        return Report {
            anchored,
            ..Report::default()
        };
    }
    // The walk needs the points still to orient and the anchors next to them, in Morton order.
    let mut needed: Vec<bool> = anchors.iter().map(|a| !a).collect();
    for i in 0..n {
        for j in graph.row(i).filter(|&j| j < n) {
            if anchors[i] != anchors[j] {
                needed[i] = true;
                needed[j] = true;
            }
        }
    }
    let subset: Vec<u32> = (0..n as u32)
        .into_par_iter()
        .filter(|&i| needed[i as usize])
        .collect();
    let near: Vec<Vec3> = subset.par_iter().map(|&i| positions[i as usize]).collect();
    let order: Vec<u32> = morton_order(&near)
        .into_par_iter()
        .map(|s| subset[s as usize])
        .collect();
    let mut rank = vec![NONE; n];
    for (s, &i) in order.iter().enumerate() {
        rank[i as usize] = s as u32;
    }
    let mut rows = vec![NONE; order.len() * GRAPH_K];
    rows.par_chunks_mut(GRAPH_K)
        .zip(&order)
        .for_each(|(row, &i)| {
            let i = i as usize;
            let kept = graph.rows[i * GRAPH_K..(i + 1) * GRAPH_K]
                .iter()
                .filter_map(|&j| rank.get(j as usize).copied())
                .filter(|&r| r != NONE);
            for (slot, r) in row.iter_mut().zip(kept) {
                *slot = r;
            }
        });
    let mut sorted: Vec<Vec3> = order.par_iter().map(|&i| normals[i as usize]).collect();
    let mut oriented: Vec<bool> = order.par_iter().map(|&i| anchors[i as usize]).collect();
    let (propagated, parts) = walk(&Graph { rows }, &mut sorted, &mut oriented, &|s, normal| {
        prior_of(order[s] as usize, normal)
    });
    for (&i, normal) in order.iter().zip(sorted) {
        normals[i as usize] = normal;
    }
    Report {
        anchored,
        propagated,
        parts,
    }
}

/// Orients every point not yet `oriented` from its neighbours in `graph` (the anchored spanning
/// forest, then one tree per part no anchor reaches, signed by the vote of `prior`). Returns
/// the points oriented and the parts voted.
fn walk(
    graph: &Graph,
    normals: &mut [Vec3],
    oriented: &mut [bool],
    prior: &(dyn Fn(usize, Vec3) -> f32 + Sync),
) -> (usize, usize) {
    let n = normals.len();
    let incoming = Incoming::new(graph, oriented);
    let mut queue = Queue::new();
    let weight = |a: Vec3, b: Vec3| a.dot(b).abs();
    // Every edge from an anchor to a point still to orient seeds the walk.
    for j in 0..n {
        if oriented[j] {
            continue;
        }
        for m in graph.row(j).chain(incoming.of(j)) {
            if oriented[m] {
                queue.push(weight(normals[m], normals[j]), m as u32, j as u32);
            }
        }
    }
    let grow = |queue: &mut Queue, normals: &mut [Vec3], oriented: &mut [bool]| {
        let mut reached = Vec::new();
        while let Some((from, to)) = queue.pop() {
            let (from, to) = (from as usize, to as usize);
            if oriented[to] {
                continue;
            }
            if normals[to].dot(normals[from]) < 0.0 {
                normals[to] = -normals[to];
            }
            oriented[to] = true;
            reached.push(to);
            for m in graph.row(to).chain(incoming.of(to)) {
                if !oriented[m] {
                    queue.push(weight(normals[to], normals[m]), to as u32, m as u32);
                }
            }
        }
        reached
    };
    let mut propagated = grow(&mut queue, normals, oriented).len();
    let mut parts = 0;
    // What no anchor reaches: one part at a time from its first point, then its sign by vote.
    for seed in 0..n {
        if oriented[seed] {
            continue;
        }
        oriented[seed] = true;
        for m in graph.row(seed).chain(incoming.of(seed)) {
            if !oriented[m] {
                queue.push(weight(normals[seed], normals[m]), seed as u32, m as u32);
            }
        }
        let mut part = grow(&mut queue, normals, oriented);
        part.push(seed);
        let vote: f32 = part.iter().map(|&i| prior(i, normals[i])).sum();
        if vote < 0.0 {
            for &i in &part {
                normals[i] = -normals[i];
            }
        }
        propagated += part.len();
        parts += 1;
    }
    (propagated, parts)
}

/// The reverse of the graph's rows where they touch a point still to orient: for each point,
/// the points that list it as a neighbour (compressed rows).
struct Incoming {
    starts: Vec<u32>,
    from: Vec<u32>,
}

impl Incoming {
    fn new(graph: &Graph, oriented: &[bool]) -> Self {
        let n = oriented.len();
        let wanted = |i: usize, j: usize| !oriented[i] || !oriented[j];
        let mut starts = vec![0u32; n + 1];
        for i in 0..n {
            for j in graph.row(i) {
                if wanted(i, j) {
                    starts[j + 1] += 1;
                }
            }
        }
        for i in 0..n {
            starts[i + 1] += starts[i];
        }
        let mut fill = starts.clone();
        let mut from = vec![0u32; starts[n] as usize];
        for i in 0..n {
            for j in graph.row(i) {
                if wanted(i, j) {
                    from[fill[j] as usize] = i as u32;
                    fill[j] += 1;
                }
            }
        }
        Incoming { starts, from }
    }

    fn of(&self, j: usize) -> impl Iterator<Item = usize> + '_ {
        self.from[self.starts[j] as usize..self.starts[j + 1] as usize]
            .iter()
            .map(|&i| i as usize)
    }
}

/// A max-priority queue of edges over [`LEVELS`] buckets of weight in [0, 1].
struct Queue {
    buckets: Vec<Vec<(u32, u32)>>,
    top: usize,
}

impl Queue {
    fn new() -> Self {
        Queue {
            buckets: vec![Vec::new(); LEVELS],
            top: 0,
        }
    }

    fn push(&mut self, weight: f32, from: u32, to: u32) {
        let level =
            ((weight.clamp(0.0, 1.0) * (LEVELS - 1) as f32).round() as usize).min(LEVELS - 1);
        self.buckets[level].push((from, to));
        self.top = self.top.max(level);
    }

    fn pop(&mut self) -> Option<(u32, u32)> {
        loop {
            if let Some(edge) = self.buckets[self.top].pop() {
                return Some(edge);
            }
            if self.top == 0 {
                return None;
            }
            self.top -= 1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A k-NN graph by brute force.
    fn graph_of(positions: &[Vec3]) -> Graph {
        let mut graph = Graph::new(positions.len());
        for (i, p) in positions.iter().enumerate() {
            let mut order: Vec<usize> = (0..positions.len()).filter(|&j| j != i).collect();
            order.sort_by(|&a, &b| {
                p.distance_squared(positions[a])
                    .total_cmp(&p.distance_squared(positions[b]))
            });
            for (slot, j) in graph.rows[i * GRAPH_K..(i + 1) * GRAPH_K]
                .iter_mut()
                .zip(order)
            {
                *slot = j as u32;
            }
        }
        graph
    }

    /// A sphere's points with their outward normals, every other one flipped.
    fn sphere() -> (Vec<Vec3>, Vec<Vec3>, Vec<Vec3>) {
        let n = 400;
        let golden = std::f32::consts::PI * (3.0 - 5f32.sqrt());
        let truth: Vec<Vec3> = (0..n)
            .map(|i| {
                let y = 1.0 - 2.0 * (i as f32 + 0.5) / n as f32;
                let r = (1.0 - y * y).sqrt();
                let a = golden * i as f32;
                Vec3::new(r * a.cos(), y, r * a.sin())
            })
            .collect();
        let flipped = truth
            .iter()
            .enumerate()
            .map(|(i, &t)| if i % 2 == 0 { -t } else { t })
            .collect();
        (truth.clone(), truth, flipped)
    }

    #[test]
    fn propagation_orients_a_sphere_outwards_from_mixed_signs() {
        let (positions, truth, mut normals) = sphere();
        let cloud = Cloud {
            positions: positions.clone(),
            ..Cloud::default()
        };
        let report = orient(&cloud, &mut normals, &graph_of(&positions), Rule::Propagate);
        assert_eq!(report.anchored, 0);
        assert_eq!(report.parts, 1);
        assert_eq!(report.propagated, positions.len());
        for (n, t) in normals.iter().zip(&truth) {
            assert!(n.dot(*t) > 0.99, "{n} against {t}");
        }
    }

    #[test]
    fn a_sensor_inside_orients_inwards_and_up_orients_the_top_up() {
        let (positions, truth, mut normals) = sphere();
        let cloud = Cloud {
            positions: positions.clone(),
            sensors: vec![Sensor {
                first: 0,
                position: Vec3::ZERO,
            }],
            ..Cloud::default()
        };
        assert_eq!(Rule::for_cloud(&cloud), Rule::Sensor);
        let graph = graph_of(&positions);
        orient(&cloud, &mut normals, &graph, Rule::Sensor);
        for (n, t) in normals.iter().zip(&truth) {
            assert!(n.dot(*t) < -0.99, "{n} against {t}");
        }
        let (_, _, mut normals) = sphere();
        let report = orient(&cloud, &mut normals, &graph, Rule::Up(Up::Y));
        assert!(report.propagated > 0 && report.anchored > 0, "{report:?}");
        for (n, p) in normals.iter().zip(&positions) {
            if p.y > 0.5 {
                assert!(n.y > 0.0, "{n} at {p}");
            }
        }
    }

    #[test]
    fn each_scan_has_its_own_scanner() {
        let sensors = [
            Sensor {
                first: 0,
                position: Vec3::X,
            },
            Sensor {
                first: 10,
                position: Vec3::Y,
            },
        ];
        assert_eq!(sensor_of(&sensors, 0), Some(Vec3::X));
        assert_eq!(sensor_of(&sensors, 9), Some(Vec3::X));
        assert_eq!(sensor_of(&sensors, 10), Some(Vec3::Y));
        assert_eq!(sensor_of(&sensors[1..], 3), None);
    }

    #[test]
    fn the_queue_pops_the_heaviest_edge_first() {
        let mut q = Queue::new();
        q.push(0.2, 1, 2);
        q.push(0.9, 3, 4);
        q.push(0.5, 5, 6);
        assert_eq!(q.pop(), Some((3, 4)));
        q.push(1.0, 7, 8);
        assert_eq!(q.pop(), Some((7, 8)));
        assert_eq!(q.pop(), Some((5, 6)));
        assert_eq!(q.pop(), Some((1, 2)));
        assert_eq!(q.pop(), None);
    }
}
