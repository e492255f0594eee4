//! What the viewer's HUD says: the statistics panel (method, per-pass GPU time, points or the
//! level-of-detail samples per level, GPU memory, frame rate) and the key help. The text is
//! rebuilt twice a second and on changes; other code extends it by appending lines to
//! `Hud::stats` before `Hud::panels`.

use std::time::{Duration, Instant};

use crate::color::LegendEntry;
use crate::layout::{LOD_COLOR_0, LOD_COLOR_1, LOD_COLOR_2, LOD_COLOR_3};
use crate::overlay::{Corner, HudLine, Panel};
use crate::scene::appearance::Edl;
use crate::scene::clip::Classes;

/// Every viewer key and mouse control, as shown by the help panel (`H`).
pub const KEYS: &[(&str, &str)] = &[
    ("left drag", "orbit about the up axis"),
    ("right drag", "pan"),
    ("wheel", "zoom"),
    ("left click", "pick / measure with the tool"),
    ("click legend", "hide / show a class"),
    ("T", "tool: pick, measure, clipping box"),
    ("X", "clear the measurement"),
    ("B", "clipping box: inside, outside, off"),
    ("F", "show every class"),
    ("M / N", "next / previous method"),
    ("[ / ]", "pyramid level shown"),
    ("+ / -", "point size or splat radius"),
    (", / .", "point or sample budget / 2, x 2"),
    ("C", "toggle point colors"),
    ("E", "toggle eye-dome lighting"),
    ("V", "color by the next field"),
    ("G", "lights: none, headlight, ring of N"),
    ("Ctrl+1 - 9", "store a camera bookmark"),
    ("1 - 9", "go to a camera bookmark"),
    ("R", "reset the camera"),
    ("K", "save camera, bookmarks, filter"),
    ("L", "load them (--camera-file)"),
    ("P", "screenshot (PNG)"),
    ("A", "play the camera path again (--path)"),
    ("H", "show / hide this help"),
    ("U", "list every pass / per-family totals"),
    ("Tab", "show / hide the HUD"),
    ("F11", "fullscreen"),
    ("Esc", "quit"),
];

/// How often the statistics are refreshed (and the frame rate averaged over).
pub const REFRESH: Duration = Duration::from_millis(500);

/// Frames per second averaged over windows of at least `REFRESH`.
pub struct FrameRate {
    start: Instant,
    frames: u32,
    /// The last window's rate (`None` before the first window closes).
    pub fps: Option<f64>,
}

impl FrameRate {
    pub fn new(now: Instant) -> Self {
        Self {
            start: now,
            frames: 0,
            fps: None,
        }
    }

    /// Counts a frame presented at `now`; true when a window closed and `fps` changed.
    pub fn tick(&mut self, now: Instant) -> bool {
        self.frames += 1;
        let elapsed = now.duration_since(self.start);
        if elapsed < REFRESH {
            return false;
        }
        self.fps = Some(f64::from(self.frames) / elapsed.as_secs_f64());
        self.start = now;
        self.frames = 0;
        true
    }
}

/// What a method projects of the cloud.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Projected {
    /// Every point.
    All,
    /// The points of the batches in view (counted on the host).
    InView(u64),
    /// The samples its level of detail selects on the GPU, per level, as read back from the
    /// newest finished frame (`None` before one finished).
    LevelOfDetail(Option<Vec<u64>>),
}

/// Characters of a level's histogram bar.
const BAR: usize = 12;

/// The splat colors of levels 0-3 (thesis Fig. 7.4: grey, yellow, blue, red), as the
/// `levels=1` parameter of the LOD methods draws them.
const LEVEL_COLORS: [u32; 4] = [LOD_COLOR_0, LOD_COLOR_1, LOD_COLOR_2, LOD_COLOR_3];

/// The HUD color of level `level` (the text color past the thesis' four levels).
fn level_color(level: usize) -> [u8; 4] {
    LEVEL_COLORS.get(level).map_or(HudLine::TEXT, |&c| {
        let [_, r, g, b] = c.to_be_bytes();
        [r, g, b, 255]
    })
}

/// One histogram line per level: the level, its samples, their share of `total` and a bar
/// of `BAR` characters (`#` for the share, `-` for the rest), tab-separated so the columns
/// line up in the proportional font; in the level's color.
fn histogram(counts: &[u64], total: u64) -> impl Iterator<Item = HudLine> + '_ {
    counts.iter().enumerate().map(move |(level, &n)| {
        let share = if total == 0 {
            0.0
        } else {
            n as f64 / total as f64
        };
        let filled = (share * BAR as f64).round() as usize;
        HudLine::new(
            format!(
                "L{level}\t{}\t{:.0} %\t{}{}",
                thousands(n),
                share * 100.0,
                "#".repeat(filled),
                "-".repeat(BAR - filled)
            ),
            level_color(level),
        )
    })
}

/// The figures the statistics panel shows.
pub struct Stats<'a> {
    pub method: &'a str,
    pub file: &'a str,
    /// Per-pass GPU milliseconds of the newest completed frame.
    pub passes: &'a [(String, f64)],
    pub points: u64,
    /// What the method projects this frame.
    pub projected: Projected,
    pub width: u32,
    pub height: u32,
    pub fps: Option<f64>,
    /// Bytes allocated and reserved by the GPU allocator.
    pub memory: Option<(u64, u64)>,
    pub use_color: bool,
    /// Eye-dome lighting as drawn (`E`), off when `None`.
    pub edl: Option<Edl>,
    /// The field colored by (`V`).
    pub color_by: &'a str,
    /// The classes present with their palette colors, shown while coloring by
    /// classification (empty otherwise).
    pub legend: &'a [LegendEntry],
    /// The last action's outcome (camera saved, screenshot written, ...).
    pub status: &'a str,
    /// A streamed file's state, one HUD line per text line: points drawn and chosen, budget,
    /// nodes, loading, bytes read.
    pub stream: Option<&'a str>,
    /// List every pass (else per-family totals).
    pub expanded: bool,
    /// The renderer has no timings yet (a new graph: its first frames are in flight).
    pub measuring: bool,
    /// Classes the filter hides (their legend lines say so).
    pub hidden: &'a Classes,
    /// The tool's and the measurement's lines.
    pub tools: &'a [HudLine],
}

/// The HUD's panels: statistics (top left) and, when asked, the key help (top right).
pub struct Hud {
    pub stats: Vec<HudLine>,
    pub help: bool,
    /// The index of the first legend line in `stats`.
    pub legend_at: usize,
}

/// The family of a pass: its name up to the first `.` (`compute.raster` is `compute`).
pub fn family(pass: &str) -> &str {
    pass.split('.').next().unwrap_or(pass)
}

/// Per family, in order of first appearance: the summed milliseconds and the pass count.
pub fn family_totals(passes: &[(String, f64)]) -> Vec<(&str, f64, usize)> {
    let mut out: Vec<(&str, f64, usize)> = Vec::new();
    for (name, ms) in passes {
        let f = family(name);
        match out.iter_mut().find(|(g, _, _)| *g == f) {
            Some(entry) => {
                entry.1 += ms;
                entry.2 += 1;
            }
            None => out.push((f, *ms, 1)),
        }
    }
    out
}

/// Characters a HUD line of free text (the method's parameters, the file's name) takes at
/// most: about a third of a 960-pixel window.
pub const LINE_CHARS: usize = 40;

/// `text` in lines of at most `width` characters, broken after commas where it can (a
/// method's `name:key=value,...`), continuation lines indented by two spaces.
pub fn wrap(text: &str, width: usize) -> Vec<String> {
    let mut lines = vec![String::new()];
    for token in text.split_inclusive(',') {
        let mut rest: Vec<char> = token.chars().collect();
        while !rest.is_empty() {
            let line = lines.last_mut().expect("one line");
            let room = width.saturating_sub(line.chars().count());
            let empty = line.trim().is_empty();
            if rest.len() <= room || (empty && room > 0) {
                let take = rest.len().min(room);
                line.extend(rest.drain(..take));
            } else {
                lines.push("  ".to_string());
            }
        }
    }
    lines
}

/// `text` shortened to `width` characters by replacing its middle with `...`.
pub fn elide(text: &str, width: usize) -> String {
    let chars: Vec<char> = text.chars().collect();
    if chars.len() <= width {
        return text.to_string();
    }
    let keep = width.saturating_sub(3);
    let head = keep / 2;
    let tail = keep - head;
    let mut out: String = chars[..head].iter().collect();
    out.push_str("...");
    out.extend(&chars[chars.len() - tail..]);
    out
}

/// Formats `n` with thousands separators.
pub fn thousands(n: u64) -> String {
    let digits = n.to_string();
    let mut out = String::with_capacity(digits.len() + digits.len() / 3);
    for (i, c) in digits.chars().enumerate() {
        if i > 0 && (digits.len() - i).is_multiple_of(3) {
            out.push(',');
        }
        out.push(c);
    }
    out
}

fn mib(bytes: u64) -> f64 {
    bytes as f64 / (1024.0 * 1024.0)
}

/// The GPU time lines: the frame's total (or that the new graph is being measured), then each
/// pass (`expanded`) or each family's total.
fn pass_lines(s: &Stats<'_>) -> Vec<HudLine> {
    let mut out = Vec::new();
    // A new graph's passes are shown once its own first frame is timed, never another's.
    let passes: &[(String, f64)] = if s.measuring { &[] } else { s.passes };
    let total: f64 = passes.iter().map(|(_, ms)| ms).sum();
    out.push(HudLine::new(
        if s.measuring || passes.is_empty() {
            let name = s.method.split(':').next().unwrap_or(s.method);
            format!("GPU: measuring {name}...")
        } else {
            format!("GPU {total:.2} ms per frame")
        },
        HudLine::TEXT,
    ));
    if s.expanded {
        for (name, ms) in passes {
            out.push(HudLine::new(format!("  {name}  {ms:.2} ms"), HudLine::DIM));
        }
    } else {
        for (name, ms, n) in family_totals(passes) {
            let passes = if n == 1 {
                String::new()
            } else {
                format!(" ({n} passes, U lists them)")
            };
            out.push(HudLine::new(
                format!("  {name}  {ms:.2} ms{passes}"),
                HudLine::DIM,
            ));
        }
    }
    out
}

/// The points line: the cloud's points and what the method projects of them.
fn points_text(s: &Stats<'_>) -> String {
    match &s.projected {
        Projected::InView(n) => format!(
            "points {}, {} projected (batches in view)",
            thousands(s.points),
            thousands(*n)
        ),
        Projected::All => format!("points {}, all projected", thousands(s.points)),
        Projected::LevelOfDetail(Some(counts)) => format!(
            "points {}, {} samples projected (level of detail)",
            thousands(s.points),
            thousands(counts.iter().sum())
        ),
        Projected::LevelOfDetail(None) => format!(
            "points {}, level of detail: waiting for the sample counts",
            thousands(s.points)
        ),
    }
}

impl Hud {
    /// The statistics lines for `s`.
    pub fn new(s: &Stats<'_>, help: bool) -> Self {
        // The method's parameters wrap and the file's name is elided, so the panel stays
        // narrow whatever they hold.
        let mut stats: Vec<HudLine> = wrap(s.method, LINE_CHARS)
            .into_iter()
            .map(|l| HudLine::new(l, HudLine::HEADING))
            .collect();
        stats.push(HudLine::new(elide(s.file, LINE_CHARS), HudLine::DIM));
        stats.extend(pass_lines(s));
        // Batch-culling methods project the points of the batches inside the frustum (counted
        // on the host with the shader's own test); level of detail projects the samples it
        // counted per level on the GPU; the others project every point.
        stats.push(HudLine::new(points_text(s), HudLine::TEXT));
        if let Projected::LevelOfDetail(Some(counts)) = &s.projected {
            stats.extend(histogram(counts, counts.iter().sum()));
        }
        for line in s.stream.iter().flat_map(|t| t.lines()) {
            stats.push(HudLine::new(line, HudLine::TEXT));
        }
        stats.push(HudLine::new(
            match s.memory {
                Some((used, reserved)) => format!(
                    "GPU memory {:.1} MiB in use, {:.1} MiB reserved",
                    mib(used),
                    mib(reserved)
                ),
                None => "GPU memory unknown".to_string(),
            },
            HudLine::TEXT,
        ));
        stats.push(HudLine::new(
            match s.fps {
                Some(fps) => format!("{fps:.1} frames/s  {}x{}", s.width, s.height),
                None => format!("- frames/s  {}x{}", s.width, s.height),
            },
            HudLine::TEXT,
        ));
        stats.push(HudLine::new(
            match s.edl {
                Some(e) => format!(
                    "eye-dome lighting on: strength {}, radius {} px (E)",
                    e.strength, e.radius
                ),
                None => "eye-dome lighting off (E)".to_string(),
            },
            HudLine::TEXT,
        ));
        stats.push(HudLine::new(
            format!("color by {} (V)", s.color_by),
            HudLine::TEXT,
        ));
        let legend_at = stats.len();
        for entry in s.legend {
            let [r, g, b] = entry.color;
            let hidden = u8::try_from(entry.class).is_ok_and(|c| s.hidden.contains(c));
            stats.push(HudLine::new(
                format!(
                    "  {:>3} {}  {}{}",
                    entry.class,
                    entry.name,
                    thousands(entry.count as u64),
                    if hidden { "  (hidden)" } else { "" }
                ),
                if hidden { HudLine::DIM } else { [r, g, b, 255] },
            ));
        }
        stats.extend(s.tools.iter().cloned());
        if !s.use_color {
            stats.push(HudLine::new("point colors off (C)", HudLine::DIM));
        }
        if !s.status.is_empty() {
            stats.push(HudLine::new(s.status, HudLine::HEADING));
        }
        stats.push(HudLine::new("H help   Tab hide HUD", HudLine::DIM));
        Self {
            stats,
            help,
            legend_at,
        }
    }

    /// The panels to draw.
    pub fn panels(&self) -> Vec<Panel> {
        let mut out = vec![Panel {
            corner: Corner::TopLeft,
            lines: self.stats.clone(),
        }];
        if self.help {
            let mut help = Panel::new(Corner::TopRight);
            help.line("Keys", HudLine::HEADING);
            for (key, what) in KEYS {
                help.line(format!("{key}\t{what}"), HudLine::TEXT);
            }
            out.push(help);
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn stats<'a>(passes: &'a [(String, f64)]) -> Stats<'a> {
        Stats {
            method: "compute:quantized=1",
            file: "autzen.las",
            passes,
            points: 110_000,
            projected: Projected::InView(54_321),
            width: 800,
            height: 600,
            fps: Some(59.94),
            memory: Some((3 << 20, 64 << 20)),
            use_color: true,
            edl: None,
            color_by: "rgb",
            legend: &[],
            status: "",
            stream: None,
            expanded: true,
            measuring: false,
            hidden: &NONE,
            tools: &[],
        }
    }

    static NONE: Classes = Classes([0; 8]);

    #[test]
    fn collapsed_the_stats_show_per_family_totals() {
        let passes = vec![
            ("hpr.sector".to_string(), 1.0),
            ("hpr.advance".to_string(), 2.5),
            ("post".to_string(), 0.25),
            ("hpr.visible".to_string(), 0.5),
        ];
        let s = Stats {
            expanded: false,
            ..stats(&passes)
        };
        let hud = Hud::new(&s, false);
        let text: Vec<&str> = hud.stats.iter().map(|l| l.text.as_str()).collect();
        assert_eq!(
            text[2..5],
            [
                "GPU 4.25 ms per frame",
                "  hpr  4.00 ms (3 passes, U lists them)",
                "  post  0.25 ms",
            ]
        );
    }

    #[test]
    fn a_new_graph_is_measuring_until_its_own_timings_arrive() {
        // Passes the caller still holds are never shown while the new graph measures.
        let passes = [("hpr.sector".to_string(), 1.0)];
        for (held, measuring) in [(&passes[..], true), (&[][..], true), (&[][..], false)] {
            let s = Stats {
                measuring,
                ..stats(held)
            };
            let hud = Hud::new(&s, false);
            let text: Vec<&str> = hud.stats.iter().map(|l| l.text.as_str()).collect();
            assert_eq!(
                text[2..4],
                [
                    "GPU: measuring compute...",
                    "points 110,000, 54,321 projected (batches in view)",
                ]
            );
        }
    }

    #[test]
    fn the_stats_panel_lists_method_passes_total_points_memory_and_rate() {
        let passes = vec![
            ("compute.project".to_string(), 1.25),
            ("compute.resolve".to_string(), 0.5),
        ];
        let hud = Hud::new(&stats(&passes), false);
        let text: Vec<&str> = hud.stats.iter().map(|l| l.text.as_str()).collect();
        assert_eq!(
            text,
            [
                "compute:quantized=1",
                "autzen.las",
                "GPU 1.75 ms per frame",
                "  compute.project  1.25 ms",
                "  compute.resolve  0.50 ms",
                "points 110,000, 54,321 projected (batches in view)",
                "GPU memory 3.0 MiB in use, 64.0 MiB reserved",
                "59.9 frames/s  800x600",
                "eye-dome lighting off (E)",
                "color by rgb (V)",
                "H help   Tab hide HUD",
            ]
        );
        assert_eq!(hud.panels().len(), 1);
        let s = Stats {
            edl: Some(Edl {
                strength: 1.0,
                radius: 1.4,
            }),
            ..stats(&passes)
        };
        let hud = Hud::new(&s, false);
        assert!(hud
            .stats
            .iter()
            .any(|l| l.text == "eye-dome lighting on: strength 1, radius 1.4 px (E)"));
    }

    #[test]
    fn methods_without_batch_culling_project_every_point() {
        let s = Stats {
            projected: Projected::All,
            ..stats(&[])
        };
        let hud = Hud::new(&s, false);
        assert!(hud
            .stats
            .iter()
            .any(|l| l.text == "points 110,000, all projected"));
        let s = Stats {
            projected: Projected::LevelOfDetail(None),
            ..stats(&[])
        };
        let hud = Hud::new(&s, false);
        assert!(hud
            .stats
            .iter()
            .any(|l| l.text == "points 110,000, level of detail: waiting for the sample counts"));
        assert!(!hud.stats.iter().any(|l| l.text.starts_with("L0")));
    }

    #[test]
    fn level_of_detail_shows_the_samples_per_level_as_a_histogram_in_the_level_colors() {
        let s = Stats {
            projected: Projected::LevelOfDetail(Some(vec![812_345, 400_000, 120_000, 0])),
            ..stats(&[])
        };
        let hud = Hud::new(&s, false);
        let at = hud
            .stats
            .iter()
            .position(|l| l.text == "points 110,000, 1,332,345 samples projected (level of detail)")
            .expect("total line");
        let lines: Vec<(&str, [u8; 4])> = hud.stats[at + 1..at + 5]
            .iter()
            .map(|l| (l.text.as_str(), l.color))
            .collect();
        assert_eq!(
            lines,
            [
                ("L0\t812,345\t61 %\t#######-----", [0x9e, 0x9e, 0x9e, 255]),
                ("L1\t400,000\t30 %\t####--------", [0xf0, 0xc8, 0x1e, 255]),
                ("L2\t120,000\t9 %\t#-----------", [0x3c, 0x64, 0xe6, 255]),
                ("L3\t0\t0 %\t------------", [0xe6, 0x3c, 0x3c, 255]),
            ]
        );
        assert_eq!(
            hud.stats[at + 5].text,
            "GPU memory 3.0 MiB in use, 64.0 MiB reserved"
        );
        // No frame's samples yet or none drawn: bars stay empty, no division by zero.
        let s = Stats {
            projected: Projected::LevelOfDetail(Some(vec![0, 0])),
            ..stats(&[])
        };
        let hud = Hud::new(&s, false);
        assert!(hud
            .stats
            .iter()
            .any(|l| l.text == "L1\t0\t0 %\t------------"));
    }

    #[test]
    fn coloring_by_classification_shows_the_legend_in_the_class_colors() {
        let legend = [
            LegendEntry {
                class: 2,
                name: "ground".into(),
                color: [170, 85, 0],
                count: 26_107,
            },
            LegendEntry {
                class: 6,
                name: "building".into(),
                color: [255, 80, 80],
                count: 9,
            },
        ];
        let hidden = Classes::from_list(&[6]);
        let s = Stats {
            color_by: "classification",
            legend: &legend,
            hidden: &hidden,
            ..stats(&[])
        };
        let hud = Hud::new(&s, false);
        assert_eq!(hud.stats[hud.legend_at].text, "    2 ground  26,107");
        let at = hud
            .stats
            .iter()
            .position(|l| l.text == "color by classification (V)")
            .expect("color line");
        assert_eq!(hud.stats[at + 1].text, "    2 ground  26,107");
        assert_eq!(hud.stats[at + 1].color, [170, 85, 0, 255]);
        assert_eq!(hud.stats[at + 2].text, "    6 building  9  (hidden)");
        assert_eq!(hud.stats[at + 2].color, HudLine::DIM);
    }

    #[test]
    fn help_lists_every_key_in_a_second_panel() {
        let hud = Hud::new(&stats(&[]), true);
        let panels = hud.panels();
        assert_eq!(panels.len(), 2);
        assert_eq!(panels[1].corner, Corner::TopRight);
        assert_eq!(panels[1].lines.len(), KEYS.len() + 1);
        for key in [
            "M / N", "C", "E", "V", "R", "K", "L", "P", "H", "Tab", "F11", "Esc",
        ] {
            assert!(
                panels[1]
                    .lines
                    .iter()
                    .any(|l| l.text.starts_with(&format!("{key}\t"))),
                "{key} missing"
            );
        }
        assert!(hud.stats[2].text.contains("measuring"));
    }

    #[test]
    fn long_parameters_wrap_and_long_file_names_are_elided() {
        let label = "lod-compute:epsilon=0.02,budget=4000000,shape=1,levels=0,max_size=16,\
                     a_parameter_name_longer_than_a_line_of_the_hud=1";
        let file = format!("/data/{}autzen.copc.laz", "deep/".repeat(20));
        let s = Stats {
            method: label,
            file: &file,
            ..stats(&[])
        };
        let hud = Hud::new(&s, false);
        let text: Vec<&str> = hud.stats.iter().map(|l| l.text.as_str()).collect();
        assert_eq!(
            text[..5],
            [
                "lod-compute:epsilon=0.02,budget=4000000,",
                "  shape=1,levels=0,max_size=16,",
                "  a_parameter_name_longer_than_a_line_of",
                "  _the_hud=1",
                "/data/deep/deep/de...eep/autzen.copc.laz",
            ]
        );
        assert!(hud
            .stats
            .iter()
            .take(5)
            .all(|l| l.text.chars().count() <= LINE_CHARS));
        let joined: String = text[..4].iter().map(|l| l.trim_start()).collect();
        assert_eq!(joined, label);
        // Short ones stay as they are.
        assert_eq!(wrap("points:size=1", LINE_CHARS), ["points:size=1"]);
        assert_eq!(elide("bun.ply", LINE_CHARS), "bun.ply");
    }

    #[test]
    fn frame_rate_averages_over_half_a_second() {
        let t0 = Instant::now();
        let mut r = FrameRate::new(t0);
        for i in 1..25 {
            assert!(!r.tick(t0 + Duration::from_millis(20 * i)));
        }
        assert!(r.tick(t0 + Duration::from_millis(500)));
        assert!((r.fps.expect("rate") - 50.0).abs() < 1e-9);
        assert_eq!(thousands(1_234_567), "1,234,567");
        assert_eq!(thousands(999), "999");
    }
}
