//! Which octree nodes a view needs, within a point budget and a memory budget.
//!
//! COPC levels are additive: a node holds a subsample of its cube at spacing
//! `spacing / 2^level`, its children hold the points between. A view therefore draws a set of
//! nodes closed under parents. The set is grown greedily from the root, as Potree does
//! (Schütz 2016, §3.3): among the nodes whose parent is chosen, the one with the largest
//! projected size (`cube half-diagonal / distance to its centre`, in pixels) comes next, while
//! it fits both budgets; a node's children are candidates only when it is in the view frustum
//! and its own point spacing ([`spacing`]) projects to more than `error_px` pixels (the
//! screen-space error: a finer level would add visible detail). The first candidate that does not fit ends the
//! selection, so a large near node is never skipped for many small far ones. The root is taken
//! even when it alone exceeds the point budget: a view always draws it.
//!
//! [`select`] uses a heap; [`select_brute_force`] rescans every node per step and exists to
//! check it.

use std::cmp::Ordering;
use std::collections::{BinaryHeap, HashMap, HashSet};

use glam::{DVec3, Mat4, Vec3};

use crate::layout::{GpuBatch, BATCH_POINTS};
use crate::point_streams::batch_visible;
use crate::scene::copc::{Entry, Info, Key, Node};

/// The hierarchy known so far: nodes with points, and pages not read yet.
#[derive(Clone, Debug, Default)]
pub struct Hierarchy {
    pub nodes: HashMap<Key, Node>,
    /// Keys whose entries (and their subtrees') are in a page not read yet: offset, bytes.
    pub pages: HashMap<Key, (u64, u64)>,
    /// Offsets of the pages read (a page referenced twice is refused).
    read: HashSet<u64>,
}

impl Hierarchy {
    /// Adds the entries of the page read at byte `at`; false when that page was read before
    /// (a cycle in a corrupt hierarchy).
    pub fn add_page(&mut self, at: u64, entries: Vec<Entry>) -> bool {
        if !self.read.insert(at) {
            return false;
        }
        for entry in entries {
            match entry {
                Entry::Node(n) => {
                    self.pages.remove(&n.key);
                    self.nodes.insert(n.key, n);
                }
                Entry::Page { key, offset, bytes } => {
                    if !self.nodes.contains_key(&key) {
                        self.pages.insert(key, (offset, bytes));
                    }
                }
            }
        }
        true
    }
}

/// The view a selection is made for, in the streamed cloud's local frame (file coordinates
/// minus the origin).
#[derive(Clone, Copy, Debug)]
pub struct SelectView {
    pub view_proj: Mat4,
    pub eye: Vec3,
    /// Pixels per radian at the image centre: `height / (2 tan(fov_y / 2))`.
    pub pixels_per_radian: f32,
    /// Screen-space error: a node is refined while its point spacing projects to more pixels.
    pub error_px: f32,
}

/// What a selection may take.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Budget {
    /// Points drawn.
    pub points: u64,
    /// Batch slots of the GPU pool (a node takes `ceil(points / BATCH_POINTS)`).
    pub slots: u64,
}

/// Batch slots a node of `points` points takes.
pub fn slots_of(points: u64) -> u64 {
    points.div_ceil(u64::from(BATCH_POINTS))
}

/// The nodes a view draws, in the order they were chosen (parents before children, larger
/// projected size first), with their totals and the unread pages the view reached.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Selection {
    pub nodes: Vec<Key>,
    pub points: u64,
    pub slots: u64,
    pub pages: Vec<Key>,
}

impl Selection {
    /// Adds `node` when it fits `budget` with what is chosen; false (nothing added) otherwise.
    fn take(&mut self, node: &Node, budget: Budget) -> bool {
        let slots = slots_of(node.points);
        if self.points + node.points > budget.points || self.slots + slots > budget.slots {
            return false;
        }
        self.points += node.points;
        self.slots += slots;
        self.nodes.push(node.key);
        true
    }
}

/// Geometry of a node for the selection, computed once per node and view.
struct Measure {
    /// Projected size (the priority).
    weight: f64,
    /// Whether the cube intersects the frustum.
    visible: bool,
    /// Whether the node's spacing projects above the error (its children add detail).
    refine: bool,
}

/// The point spacing of node `n`: the larger of the file's nominal spacing at its level
/// (`info.spacing / 2^level`) and what its points give on a surface through its cube
/// (`edge / sqrt(points)`: scans and LiDAR sample 2-manifolds). Writers set the nominal value
/// from the cube alone (half size / 128, as `copc-writer` and this project's writer do),
/// whatever the points per node.
pub fn spacing(info: &Info, n: &Node) -> f64 {
    let scale = f64::from(1u32 << n.key.level.clamp(0, 31));
    let edge = 2.0 * info.halfsize / scale;
    (info.spacing / scale).max(edge / (n.points.max(1) as f64).sqrt())
}

fn measure(node: &Node, info: &Info, origin: DVec3, view: &SelectView) -> Measure {
    let (lo, hi) = info.cube(node.key);
    let (weight, visible, distance) = measure_box(lo, hi, origin, view);
    let px = f64::from(view.pixels_per_radian);
    Measure {
        weight,
        visible,
        refine: spacing(info, node) / distance * px > f64::from(view.error_px),
    }
}

/// A candidate in the heap: larger weight first, then the smaller key.
struct Candidate {
    weight: f64,
    key: Key,
}

impl PartialEq for Candidate {
    fn eq(&self, other: &Self) -> bool {
        self.cmp(other) == Ordering::Equal
    }
}

impl Eq for Candidate {}

impl PartialOrd for Candidate {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

impl Ord for Candidate {
    fn cmp(&self, other: &Self) -> Ordering {
        self.weight
            .total_cmp(&other.weight)
            .then_with(|| other.key.cmp(&self.key))
    }
}

/// The children of `key` a selection may take next (when `key` is visible and too coarse),
/// and the unread pages among them.
fn expand(h: &Hierarchy, key: Key, m: &Measure, pages: &mut Vec<Key>) -> Vec<Key> {
    if !(m.visible && m.refine) {
        return Vec::new();
    }
    let children = key.children();
    pages.extend(children.iter().filter(|c| h.pages.contains_key(c)));
    children
        .into_iter()
        .filter(|c| h.nodes.contains_key(c))
        .collect()
}

/// `budget` with its point budget raised to the root node's points: the root is drawn
/// whatever the point budget (a view without it would be empty).
fn with_root(h: &Hierarchy, budget: Budget) -> Budget {
    let root = h.nodes.get(&Key::ROOT).map_or(0, |n| n.points);
    Budget {
        points: budget.points.max(root),
        ..budget
    }
}

/// The nodes `view` draws from `h` within `budget` (see the module documentation).
pub fn select(
    h: &Hierarchy,
    info: &Info,
    origin: DVec3,
    view: &SelectView,
    budget: Budget,
) -> Selection {
    let tree = Tree {
        hierarchy: Some(h),
        info,
        bounds: info.cube(Key::ROOT),
    };
    let forest = select_forest(&[tree], origin, view, budget);
    Selection {
        nodes: forest.nodes.into_iter().map(|(_, k)| k).collect(),
        points: forest.points,
        slots: forest.slots,
        pages: forest.pages.into_iter().map(|(_, k)| k).collect(),
    }
}

/// One octree of a forest (the files of a virtual point cloud).
#[derive(Clone, Copy, Debug)]
pub struct Tree<'a> {
    /// What is known of its hierarchy; `None` while the file is not opened.
    pub hierarchy: Option<&'a Hierarchy>,
    pub info: &'a Info,
    /// Its bounds (file coordinates), for a file not opened yet.
    pub bounds: (DVec3, DVec3),
}

/// A forest's selection: nodes and pages by tree index, and the trees to open.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ForestSelection {
    pub nodes: Vec<(usize, Key)>,
    pub points: u64,
    pub slots: u64,
    pub pages: Vec<(usize, Key)>,
    /// Trees not opened whose bounds the view reaches, most wanted first.
    pub open: Vec<usize>,
}

/// A forest's candidate: larger weight first, then the smaller tree and key.
struct TreeCandidate {
    weight: f64,
    tree: usize,
    key: Key,
}

impl PartialEq for TreeCandidate {
    fn eq(&self, other: &Self) -> bool {
        self.cmp(other) == Ordering::Equal
    }
}

impl Eq for TreeCandidate {}

impl PartialOrd for TreeCandidate {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

impl Ord for TreeCandidate {
    fn cmp(&self, other: &Self) -> Ordering {
        self.weight
            .total_cmp(&other.weight)
            .then_with(|| other.tree.cmp(&self.tree))
            .then_with(|| other.key.cmp(&self.key))
    }
}

/// The projected size, the visibility and the eye's distance of the box `lo..hi` (file
/// coordinates).
fn measure_box(lo: DVec3, hi: DVec3, origin: DVec3, view: &SelectView) -> (f64, bool, f64) {
    let (lo, hi) = ((lo - origin).as_vec3(), (hi - origin).as_vec3());
    let centre = (lo + hi) * 0.5;
    let radius = f64::from((hi - lo).length() * 0.5);
    let distance = f64::from((centre - view.eye).length()).max(radius * 1e-3);
    let cube = GpuBatch {
        min_x: lo.x,
        min_y: lo.y,
        min_z: lo.z,
        first: 0,
        max_x: hi.x,
        max_y: hi.y,
        max_z: hi.z,
        count: 0,
    };
    (
        radius / distance * f64::from(view.pixels_per_radian),
        batch_visible(view.view_proj, &cube),
        distance,
    )
}

/// The nodes `view` draws from the forest `trees` within one `budget`: the selection of
/// [`select`] grown over every tree at once. The roots come first: with one tree its root is
/// drawn whatever the budget; with several, every tree whose root (its cube, or its bounds
/// before it is opened) is in the view frustum has its root drawn whatever the point budget
/// (as far as the pool holds them), so no part of the view is left empty; the point budget
/// is raised to those roots' points. A tree not opened yet that the view reaches is listed in
/// [`ForestSelection::open`] instead (its points are unknown until then). The roots' children
/// then grow the selection by projected size until the first one that does not fit.
pub fn select_forest(
    trees: &[Tree],
    origin: DVec3,
    view: &SelectView,
    budget: Budget,
) -> ForestSelection {
    let single = trees.len() == 1;
    let mut out = ForestSelection::default();
    let mut roots = Vec::new();
    for (i, t) in trees.iter().enumerate() {
        let (weight, visible) = match t.hierarchy.and_then(|h| h.nodes.get(&Key::ROOT)) {
            Some(root) => {
                let m = measure(root, t.info, origin, view);
                (m.weight, m.visible)
            }
            None if t.hierarchy.is_some() => continue,
            None => {
                let (weight, visible, _) = measure_box(t.bounds.0, t.bounds.1, origin, view);
                (weight, visible)
            }
        };
        if single || visible {
            roots.push(TreeCandidate {
                weight,
                tree: i,
                key: Key::ROOT,
            });
        }
    }
    roots.sort_by(|a, b| b.cmp(a));
    let mut heap = BinaryHeap::new();
    for TreeCandidate { tree, .. } in roots {
        let t = &trees[tree];
        let Some(h) = t.hierarchy else {
            out.open.push(tree);
            continue;
        };
        let node = &h.nodes[&Key::ROOT];
        let slots = slots_of(node.points);
        if out.slots + slots > budget.slots {
            continue;
        }
        out.points += node.points;
        out.slots += slots;
        out.nodes.push((tree, Key::ROOT));
        grow(
            h,
            tree,
            t.info,
            node,
            origin,
            view,
            &mut heap,
            &mut out.pages,
        );
    }
    let points = budget.points.max(out.points);
    while let Some(TreeCandidate { tree, key, .. }) = heap.pop() {
        let t = &trees[tree];
        let h = t.hierarchy.expect("only opened trees have children");
        let node = &h.nodes[&key];
        let slots = slots_of(node.points);
        if out.points + node.points > points || out.slots + slots > budget.slots {
            break;
        }
        out.points += node.points;
        out.slots += slots;
        out.nodes.push((tree, key));
        grow(
            h,
            tree,
            t.info,
            node,
            origin,
            view,
            &mut heap,
            &mut out.pages,
        );
    }
    out.pages.sort();
    out
}

/// Pushes the children `node` of tree `tree` opens (see [`expand`]) onto `heap` and the unread
/// pages among them onto `pages`.
#[allow(clippy::too_many_arguments)]
fn grow(
    h: &Hierarchy,
    tree: usize,
    info: &Info,
    node: &Node,
    origin: DVec3,
    view: &SelectView,
    heap: &mut BinaryHeap<TreeCandidate>,
    pages: &mut Vec<(usize, Key)>,
) {
    let m = measure(node, info, origin, view);
    let mut reached = Vec::new();
    for child in expand(h, node.key, &m, &mut reached) {
        heap.push(TreeCandidate {
            weight: measure(&h.nodes[&child], info, origin, view).weight,
            tree,
            key: child,
        });
    }
    pages.extend(reached.into_iter().map(|k| (tree, k)));
}

/// [`select`] by rescanning every known node at each step: the same rule, no heap.
pub fn select_brute_force(
    h: &Hierarchy,
    info: &Info,
    origin: DVec3,
    view: &SelectView,
    budget: Budget,
) -> Selection {
    let budget = with_root(h, budget);
    let mut out = Selection::default();
    let mut chosen = HashSet::new();
    loop {
        let best = h
            .nodes
            .values()
            .filter(|n| !chosen.contains(&n.key))
            .filter(|n| {
                if n.key == Key::ROOT {
                    return true;
                }
                chosen.contains(&n.key.parent()) && open_parent(h, &n.key, info, origin, view)
            })
            .map(|n| Candidate {
                weight: measure(n, info, origin, view).weight,
                key: n.key,
            })
            .max();
        let Some(best) = best else { break };
        let node = &h.nodes[&best.key];
        if !out.take(node, budget) {
            break;
        }
        chosen.insert(best.key);
    }
    out.pages = h
        .pages
        .keys()
        .filter(|k| chosen.contains(&k.parent()) && open_parent(h, k, info, origin, view))
        .copied()
        .collect();
    out.pages.sort();
    out
}

fn open_parent(h: &Hierarchy, key: &Key, info: &Info, origin: DVec3, view: &SelectView) -> bool {
    h.nodes.get(&key.parent()).is_some_and(|p| {
        let m = measure(p, info, origin, view);
        m.visible && m.refine
    })
}
