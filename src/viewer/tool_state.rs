//! The tools' state: the click tool (`T` cycles it) with its picks and measurement, the
//! filter and the last clipping box, the tool commands waiting for a frame, the camera
//! bookmarks, and the markers they draw over the frame.

use glam::{DVec3, Mat4, Vec3, Vec4};

use super::script::Tool;
use super::tools::{self, Measure};
use crate::overlay::{HudLine, Mark};
use crate::scene::clip::{ClipBox, Filter, Keep};
use crate::scene::scene_file::{Bookmark, SceneFile};
use crate::scene::Camera;

/// What a left click does (`T` cycles).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ClickTool {
    /// Show the point's coordinates and attributes.
    Pick,
    Measure(Measure),
    /// Two picks: an axis-aligned clipping box over their plan rectangle, the cloud's whole
    /// height.
    Box,
    /// Three picks: an edge, then the side the box extends to (an oriented box, the cloud's
    /// whole height).
    Oriented,
}

impl ClickTool {
    pub const ALL: [ClickTool; 7] = [
        ClickTool::Pick,
        ClickTool::Measure(Measure::Distance),
        ClickTool::Measure(Measure::Height),
        ClickTool::Measure(Measure::Polyline),
        ClickTool::Measure(Measure::Area),
        ClickTool::Box,
        ClickTool::Oriented,
    ];

    pub fn name(self) -> &'static str {
        match self {
            ClickTool::Pick => "pick",
            ClickTool::Measure(m) => m.name(),
            ClickTool::Box => "clipping box",
            ClickTool::Oriented => "oriented clipping box",
        }
    }

    /// Picks the tool takes before it acts (`None`: any number, each one acts).
    pub fn points(self) -> Option<usize> {
        match self {
            ClickTool::Pick => Some(1),
            ClickTool::Measure(m) => m.points(),
            ClickTool::Box => Some(2),
            ClickTool::Oriented => Some(3),
        }
    }
}

/// The tools' state: the click tool with its picks and measurement, the filter with the last
/// clipping box, the tool commands waiting for a frame, and the camera bookmarks.
pub(super) struct ToolState {
    /// What a left click does (`T`).
    pub tool: ClickTool,
    /// The current tool's picked points (file coordinates) and what they measure.
    pub picks: Vec<DVec3>,
    pub measured: Vec<(&'static str, f64)>,
    /// The clipping box and hidden classes the projection passes apply.
    pub filter: Filter,
    /// The last clipping box set (kept, not drawn, while clipping is off: `B` turns it back on).
    pub clip_box: Option<ClipBox>,
    /// `hpr::spacing` of the cloud for picking (computed on the first pick).
    pub spacing: Option<f64>,
    /// Tool commands waiting for the next frame's depth.
    pub requests: Vec<Tool>,
    pub bookmarks: Vec<Bookmark>,
}

impl ToolState {
    /// The picking tool, no picks, and the filter and bookmarks given at start.
    pub fn new(filter: Filter, bookmarks: Vec<Bookmark>) -> Self {
        Self {
            tool: ClickTool::Pick,
            picks: Vec::new(),
            measured: Vec::new(),
            filter,
            clip_box: filter.clip,
            spacing: None,
            requests: Vec::new(),
            bookmarks,
        }
    }

    /// `T`: the next click tool, with no picks.
    pub fn next_tool(&mut self) {
        let at = ClickTool::ALL
            .iter()
            .position(|t| *t == self.tool)
            .unwrap_or(0);
        self.tool = ClickTool::ALL[(at + 1) % ClickTool::ALL.len()];
        self.clear();
    }

    /// `X`: forgets the picks and the measurement.
    pub fn clear(&mut self) {
        self.picks.clear();
        self.measured.clear();
    }

    /// Takes a loaded camera file's filter, clipping box (when it has one) and bookmarks.
    pub fn take_file(&mut self, file: SceneFile) {
        self.filter = file.filter();
        if file.clip.is_some() {
            self.clip_box = file.clip;
        }
        self.bookmarks = file.bookmarks;
    }

    /// Sets (or clears) the clipping box, remembering the box when it is switched off.
    pub fn set_clip(&mut self, clip: Option<ClipBox>) {
        if clip.is_some() {
            self.clip_box = clip;
        }
        self.filter.clip = clip;
    }

    /// Stores `camera` (local coordinates about `origin`) as bookmark `slot`.
    pub fn store_bookmark(&mut self, slot: u8, camera: &Camera, origin: DVec3) {
        let b = Bookmark {
            slot,
            eye: (origin + camera.eye.as_dvec3()).to_array(),
            target: (origin + camera.target.as_dvec3()).to_array(),
        };
        self.bookmarks.retain(|b| b.slot != slot);
        self.bookmarks.push(b);
        self.bookmarks.sort_by_key(|b| b.slot);
    }

    /// Appends the markers of the clipping box while it clips, the measurement's lines and the
    /// picked points, placed by `at` (a file point's window position, `None` behind the eye).
    pub fn push_marks(&self, out: &mut Vec<Mark>, at: impl Fn(DVec3) -> Option<Vec3>) {
        if let Some(b) = self.filter.clip {
            let corners = b.corners().map(&at);
            for (i, j) in [
                (0, 1),
                (2, 3),
                (4, 5),
                (6, 7),
                (0, 2),
                (1, 3),
                (4, 6),
                (5, 7),
                (0, 4),
                (1, 5),
                (2, 6),
                (3, 7),
            ] {
                if let (Some(a), Some(b)) = (corners[i], corners[j]) {
                    dotted(out, a, b, BOX);
                }
            }
        }
        let n = self.picks.len();
        let lines = match self.tool {
            ClickTool::Measure(Measure::Area) if n > 2 => n,
            ClickTool::Measure(_) => n.saturating_sub(1),
            _ => 0,
        };
        for k in 0..lines {
            if let (Some(a), Some(b)) = (at(self.picks[k]), at(self.picks[(k + 1) % n])) {
                dotted(out, a, b, MARKER);
            }
        }
        for p in self.picks.iter().filter_map(|&p| at(p)) {
            out.push(Mark {
                rect: Vec4::new(p.x - 5.0, p.y - 5.0, p.x + 5.0, p.y + 5.0),
                color: OUTLINE,
            });
            out.push(Mark {
                rect: Vec4::new(p.x - 3.0, p.y - 3.0, p.x + 3.0, p.y + 3.0),
                color: MARKER,
            });
        }
    }

    /// The HUD lines of the tool and the measurement.
    pub fn lines(&self) -> Vec<HudLine> {
        let mut out = vec![HudLine::new(
            format!("tool: {} (T), click to pick, X clears", self.tool.name()),
            HudLine::TEXT,
        )];
        for (name, v) in &self.measured {
            out.push(HudLine::new(
                tools::measure_line(name, *v),
                HudLine::HEADING,
            ));
        }
        if let Some(b) = self.filter.clip {
            let keep = match b.keep {
                Keep::Inside => "inside",
                Keep::Outside => "outside",
            };
            out.push(HudLine::new(
                format!(
                    "clip {keep}: centre {:.2}, {:.2}, {:.2}, half {:.2}, {:.2}, {:.2} (B)",
                    b.centre[0], b.centre[1], b.centre[2], b.half[0], b.half[1], b.half[2]
                ),
                HudLine::TEXT,
            ));
        }
        out
    }
}

/// Marker colors: picked points, measurement lines, the clipping box.
const MARKER: [u8; 4] = [255, 214, 102, 255];
const OUTLINE: [u8; 4] = [20, 20, 20, 255];
const BOX: [u8; 4] = [110, 200, 255, 255];

/// Dotted-line quads between two projected points, about 6 pixels apart.
fn dotted(out: &mut Vec<Mark>, a: Vec3, b: Vec3, color: [u8; 4]) {
    let d = (b - a).truncate();
    let n = (d.length() / 6.0).ceil().clamp(1.0, 200.0) as usize;
    for k in 0..=n {
        let p = a.truncate() + d * (k as f32 / n as f32);
        out.push(Mark {
            rect: Vec4::new(p.x - 1.0, p.y - 1.0, p.x + 1.0, p.y + 1.0),
            color,
        });
    }
}

/// Window position of local point `p` (x, y in pixels, z > 0 in front), `None` behind the eye.
pub(super) fn window_of(view_proj: Mat4, p: Vec3, width: u32, height: u32) -> Option<Vec3> {
    let c = view_proj * p.extend(1.0);
    (c.w > 0.0).then(|| {
        Vec3::new(
            (c.x / c.w * 0.5 + 0.5) * width as f32,
            (c.y / c.w * 0.5 + 0.5) * height as f32,
            c.w,
        )
    })
}
