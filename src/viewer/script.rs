//! Viewer keys and scripted tours (`surfel view FILE --script SCRIPT`).
//!
//! A script is one command per line, run through the same key handler as real key events:
//!
//! ```text
//! # comments start with '#'
//! frames 3               # render 3 frames
//! key Tab                # a letter, Tab, F11 or Esc
//! orbit 30,20            # azimuth, elevation in degrees about the orbit target
//! size 640x480           # resize the window (waits until the window has that size)
//! screenshot hud.png     # render one frame and write it as PNG
//! key ctrl+3             # store camera bookmark 3 (`key 3` recalls it)
//! pick 320 240           # pick at a pixel; prints JSON
//! measure distance 10 20 300 40   # pick each pixel and measure (distance, height,
//!                                 # polyline, area); prints JSON
//! locate 512345.6 4123456.7 250   # the pixel a file coordinate is drawn at; prints JSON
//! clip box 0 0 0 10 10 5          # an axis-aligned box by two corners (file coordinates)
//! clip oriented 5 5 2 4 1 3 30    # centre, half extents, yaw [pitch roll] in degrees
//! clip outside                    # keep the outside (inside, off)
//! filter hide 2 7                 # hide classes (show, only; `filter all` shows all)
//! count                  # render a frame and print the pixels it covers; prints JSON
//! click 320 240          # a left click at a pixel (the current tool, or a legend class)
//! quit                   # (the viewer also quits at the end of the script)
//! ```

use std::path::{Path, PathBuf};

use anyhow::{bail, Context as _, Result};
use winit::keyboard::{Key, NamedKey};

use super::tools::Measure;
use crate::scene::camera::parse_floats;
use crate::scene::clip::{ClipBox, Keep};

/// A key the viewer handles.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ViewerKey {
    /// A letter or digit (lowercase), or one of `[ ] , . + - =`.
    Char(char),
    /// A digit with Ctrl held (store a camera bookmark).
    Ctrl(char),
    Tab,
    F11,
    Escape,
}

impl ViewerKey {
    /// Parses a script key name: one letter or digit (any case), `[`, `]`, `,`, `.`, `+`, `-`
    /// or `=`, `ctrl+DIGIT`, `Tab`, `F11`, `Esc` or `Escape` (names in any case).
    pub fn parse(name: &str) -> Option<Self> {
        let mut chars = name.chars();
        match (chars.next(), chars.next()) {
            (Some(c), None) if c.is_ascii_alphanumeric() || "[],.+-=".contains(c) => {
                return Some(Self::Char(c.to_ascii_lowercase()))
            }
            _ => {}
        }
        if let Some(rest) = name.to_ascii_lowercase().strip_prefix("ctrl+") {
            let mut chars = rest.chars();
            return match (chars.next(), chars.next()) {
                (Some(c @ '1'..='9'), None) => Some(Self::Ctrl(c)),
                _ => None,
            };
        }
        match name.to_ascii_lowercase().as_str() {
            "tab" => Some(Self::Tab),
            "f11" => Some(Self::F11),
            "esc" | "escape" => Some(Self::Escape),
            _ => None,
        }
    }

    /// The viewer key of a winit key event, if it is one (`ctrl`: Ctrl is held).
    pub fn from_winit(key: &Key, ctrl: bool) -> Option<Self> {
        match key.as_ref() {
            Key::Named(NamedKey::Tab) => Some(Self::Tab),
            Key::Named(NamedKey::F11) => Some(Self::F11),
            Key::Named(NamedKey::Escape) => Some(Self::Escape),
            Key::Character(s) if ctrl => Self::parse(&format!("ctrl+{s}")),
            Key::Character(s) => Self::parse(s),
            _ => None,
        }
    }
}

/// One script command.
#[derive(Clone, Debug, PartialEq)]
pub enum Step {
    Key(ViewerKey),
    /// Render this many frames.
    Frames(u64),
    /// Render one frame and write it to this PNG.
    Screenshot(PathBuf),
    /// Set the orbit's azimuth and elevation (degrees).
    Orbit(f32, f32),
    /// Resize the window.
    Size(u32, u32),
    /// A tool command (picking, measuring, clipping, filtering); prints JSON.
    Tool(Tool),
    Quit,
}

/// A scripted tool command.
#[derive(Clone, Debug, PartialEq)]
pub enum Tool {
    /// Pick at a pixel.
    Pick(i32, i32),
    /// Pick each pixel and measure.
    Measure(Measure, Vec<(i32, i32)>),
    /// The pixel a file coordinate is drawn at.
    Locate([f64; 3]),
    /// Set the clipping box.
    ClipBox(ClipBox),
    /// Keep the inside or the outside of the box.
    ClipKeep(Keep),
    ClipOff,
    /// Hide classes (`true`) or show them (`false`); `only` hides every other class.
    Filter {
        classes: Vec<u8>,
        hide: bool,
    },
    FilterOnly(Vec<u8>),
    FilterAll,
    /// Render a frame and count the pixels it covers.
    Count,
    /// A left click at a pixel.
    Click(i32, i32),
}

impl Tool {
    /// Whether the command needs a frame's depth (then it runs after the next frame).
    pub fn needs_frame(&self) -> bool {
        matches!(
            self,
            Tool::Pick(..) | Tool::Measure(..) | Tool::Count | Tool::Click(..)
        )
    }
}

fn numbers<T: std::str::FromStr>(arg: &str) -> Option<Vec<T>> {
    arg.split_whitespace().map(|t| t.parse().ok()).collect()
}

/// A `clip` command: `word` is its first argument, `rest` the others, `arg` all of them.
fn parse_clip(word: &str, rest: &str, arg: &str) -> Result<Tool, String> {
    match word {
        "box" => match numbers::<f64>(rest).as_deref() {
            Some([x0, y0, z0, x1, y1, z1]) => {
                let b = ClipBox::aligned([*x0, *y0, *z0].into(), [*x1, *y1, *z1].into());
                b.check().map(|()| Tool::ClipBox(b))
            }
            _ => Err(format!(
                "expected `clip box X0 Y0 Z0 X1 Y1 Z1`, got {rest:?}"
            )),
        },
        "oriented" => match numbers::<f64>(rest).as_deref() {
            Some([cx, cy, cz, hx, hy, hz, angles @ ..])
                if angles.len() == 1 || angles.len() == 3 =>
            {
                let b = ClipBox {
                    centre: [*cx, *cy, *cz],
                    half: [*hx, *hy, *hz],
                    rotation: [
                        angles[0],
                        *angles.get(1).unwrap_or(&0.0),
                        *angles.get(2).unwrap_or(&0.0),
                    ],
                    keep: Keep::Inside,
                };
                b.check().map(|()| Tool::ClipBox(b))
            }
            _ => Err(format!(
                "expected `clip oriented CX CY CZ HX HY HZ YAW [PITCH ROLL]`, got {rest:?}"
            )),
        },
        "inside" if rest.is_empty() => Ok(Tool::ClipKeep(Keep::Inside)),
        "outside" if rest.is_empty() => Ok(Tool::ClipKeep(Keep::Outside)),
        "off" if rest.is_empty() => Ok(Tool::ClipOff),
        _ => Err(format!(
            "expected `clip box|oriented|inside|outside|off`, got {arg:?}"
        )),
    }
}

fn parse_tool(command: &str, arg: &str) -> Result<Tool, String> {
    let (word, rest) = arg.split_once(char::is_whitespace).unwrap_or((arg, ""));
    let rest = rest.trim();
    match command {
        "pick" | "click" => match numbers::<i32>(arg).as_deref() {
            Some([x, y]) if command == "pick" => Ok(Tool::Pick(*x, *y)),
            Some([x, y]) => Ok(Tool::Click(*x, *y)),
            _ => Err(format!("expected `{command} X Y` in pixels, got {arg:?}")),
        },
        "measure" => {
            let kind = Measure::parse(word).ok_or_else(|| {
                format!("expected `measure distance|height|polyline|area X Y X Y ...`, got {arg:?}")
            })?;
            let v = numbers::<i32>(rest)
                .filter(|v| v.len() % 2 == 0)
                .ok_or_else(|| {
                    format!("expected pixel pairs X Y after `measure {word}`, got {rest:?}")
                })?;
            let pixels: Vec<(i32, i32)> = v.chunks(2).map(|c| (c[0], c[1])).collect();
            let least = match kind {
                Measure::Area => 3,
                _ => 2,
            };
            if pixels.len() < least || kind.points().is_some_and(|n| n != pixels.len()) {
                return Err(format!(
                    "`measure {word}` takes {} pixels, got {}",
                    kind.points()
                        .map_or(format!("at least {least}"), |n| n.to_string()),
                    pixels.len()
                ));
            }
            Ok(Tool::Measure(kind, pixels))
        }
        "locate" => match numbers::<f64>(arg).as_deref() {
            Some([x, y, z]) if [x, y, z].iter().all(|v| v.is_finite()) => {
                Ok(Tool::Locate([*x, *y, *z]))
            }
            _ => Err(format!(
                "expected `locate X Y Z` in file coordinates, got {arg:?}"
            )),
        },
        "clip" => parse_clip(word, rest, arg),
        "filter" => {
            let classes = || {
                numbers::<u8>(rest)
                    .filter(|c| !c.is_empty())
                    .ok_or_else(|| {
                        format!("expected classes 0-255 after `filter {word}`, got {rest:?}")
                    })
            };
            match word {
                "hide" => Ok(Tool::Filter {
                    classes: classes()?,
                    hide: true,
                }),
                "show" => Ok(Tool::Filter {
                    classes: classes()?,
                    hide: false,
                }),
                "only" => Ok(Tool::FilterOnly(classes()?)),
                "all" if rest.is_empty() => Ok(Tool::FilterAll),
                _ => Err(format!(
                    "expected `filter hide|show|only CLASSES` or `filter all`, got {arg:?}"
                )),
            }
        }
        _ if arg.is_empty() => Ok(Tool::Count),
        _ => Err(format!("expected `count` alone, got {arg:?} after it")),
    }
}

/// A parsed script: its steps, in order.
#[derive(Clone, Debug, PartialEq)]
pub struct Script {
    pub steps: Vec<Step>,
}

impl Script {
    /// Reads and parses `path`.
    pub fn load(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path)
            .with_context(|| format!("{}: cannot read script", path.display()))?;
        Self::parse(&text, path)
    }

    /// Parses `text`; errors name `path` and the line: `SCRIPT:LINE: expected ...`.
    pub fn parse(text: &str, path: &Path) -> Result<Self> {
        let mut steps = Vec::new();
        for (i, raw) in text.lines().enumerate() {
            let line = raw.split('#').next().unwrap_or("").trim();
            if line.is_empty() {
                continue;
            }
            let (command, arg) = match line.split_once(char::is_whitespace) {
                Some((c, a)) => (c, a.trim()),
                None => (line, ""),
            };
            let step = parse_step(command, arg)
                .map_err(|expected| anyhow::anyhow!("{}:{}: {expected}", path.display(), i + 1))?;
            steps.push(step);
        }
        Ok(Self { steps })
    }
}

fn parse_step(command: &str, arg: &str) -> Result<Step, String> {
    match command {
        "key" => ViewerKey::parse(arg).map(Step::Key).ok_or_else(|| {
            format!("expected `key NAME` with NAME a letter, a digit, ctrl+DIGIT, [, ], ',', ., +, -, Tab, F11 or Esc, got {arg:?}")
        }),
        "frames" => match arg.parse::<u64>() {
            Ok(n) if n >= 1 => Ok(Step::Frames(n)),
            _ => Err(format!(
                "expected `frames N` with N a whole number >= 1, got {arg:?}"
            )),
        },
        "screenshot" if !arg.is_empty() => Ok(Step::Screenshot(PathBuf::from(arg))),
        "screenshot" => Err("expected `screenshot PATH`".into()),
        "orbit" => match parse_floats(arg).as_deref() {
            Ok([az, el]) if (-90.0..=90.0).contains(el) => Ok(Step::Orbit(*az, *el)),
            _ => Err(format!(
                "expected `orbit AZ,EL` in degrees (elevation within -90..=90), got {arg:?}"
            )),
        },
        "size" => crate::frame::Size::parse(arg)
            .map(|s| Step::Size(s.width, s.height))
            .map_err(|e| format!("expected `size WxH`: {e}")),
        "quit" if arg.is_empty() => Ok(Step::Quit),
        "quit" => Err(format!("expected `quit` alone, got {arg:?} after it")),
        "pick" | "click" | "measure" | "locate" | "clip" | "filter" | "count" => {
            parse_tool(command, arg).map(Step::Tool)
        }
        _ => Err(format!(
            "expected key, frames, screenshot, orbit, size, pick, measure, locate, clip, filter, count, click or quit, got {command:?}"
        )),
    }
}

/// What the viewer does next while running a script.
#[derive(Clone, Debug, PartialEq)]
pub enum Next {
    /// Apply a key, then ask again.
    Key(ViewerKey),
    /// Set the orbit angles, then ask again.
    Orbit(f32, f32),
    /// Resize the window, render until it has that size, then ask again.
    Size(u32, u32),
    /// Render a frame (writing it to the path when given).
    Frame(Option<PathBuf>),
    /// Run a tool command (one that needs a frame's depth runs after the next frame).
    Tool(Tool),
    /// The script is over.
    Quit,
}

/// A script being run: which step is next and how many frames the current `frames` step has
/// left.
pub struct Runner {
    script: Script,
    next: usize,
    frames_left: u64,
}

impl Runner {
    pub fn new(script: Script) -> Self {
        Self {
            script,
            next: 0,
            frames_left: 0,
        }
    }

    /// The next action; a frame action is counted as rendered.
    pub fn step(&mut self) -> Next {
        if self.frames_left > 0 {
            self.frames_left -= 1;
            return Next::Frame(None);
        }
        let Some(step) = self.script.steps.get(self.next) else {
            return Next::Quit;
        };
        self.next += 1;
        match step {
            Step::Key(k) => Next::Key(*k),
            Step::Orbit(az, el) => Next::Orbit(*az, *el),
            Step::Size(w, h) => Next::Size(*w, *h),
            Step::Tool(t) => Next::Tool(t.clone()),
            Step::Frames(n) => {
                self.frames_left = n - 1;
                Next::Frame(None)
            }
            Step::Screenshot(p) => Next::Frame(Some(p.clone())),
            Step::Quit => {
                self.next = self.script.steps.len();
                Next::Quit
            }
        }
    }
}

/// Checks `path` can hold a camera (a scene file: `.toml` or `.json`).
pub fn check_camera_file(path: &Path) -> Result<()> {
    match path.extension().and_then(|e| e.to_str()) {
        Some("toml" | "json") => Ok(()),
        _ => bail!(
            "{}: camera files are scene files and must end in .toml or .json",
            path.display()
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_every_command_with_comments_and_blank_lines() {
        let s = Script::parse(
            "# tour\n\nframes 3\nkey Tab   # hide\nkey h\nkey F11\nkey esc\norbit 30,-20.5\nsize 64x48\n\
             screenshot out/a b.png\nquit\n",
            Path::new("t.txt"),
        )
        .expect("valid");
        assert_eq!(
            s.steps,
            vec![
                Step::Frames(3),
                Step::Key(ViewerKey::Tab),
                Step::Key(ViewerKey::Char('h')),
                Step::Key(ViewerKey::F11),
                Step::Key(ViewerKey::Escape),
                Step::Orbit(30.0, -20.5),
                Step::Size(64, 48),
                Step::Screenshot(PathBuf::from("out/a b.png")),
                Step::Quit,
            ]
        );
        assert_eq!(ViewerKey::parse("M"), Some(ViewerKey::Char('m')));
        assert_eq!(ViewerKey::parse("]"), Some(ViewerKey::Char(']')));
        assert_eq!(
            ViewerKey::from_winit(&Key::Character("K".into()), false),
            Some(ViewerKey::Char('k'))
        );
        assert_eq!(
            ViewerKey::from_winit(&Key::Named(NamedKey::Tab), false),
            Some(ViewerKey::Tab)
        );
        assert_eq!(
            ViewerKey::from_winit(&Key::Named(NamedKey::F1), false),
            None
        );
        assert_eq!(
            ViewerKey::from_winit(&Key::Character("3".into()), true),
            Some(ViewerKey::Ctrl('3'))
        );
        assert_eq!(ViewerKey::parse("ctrl+0"), None);
        assert_eq!(ViewerKey::parse("+"), Some(ViewerKey::Char('+')));
    }

    #[test]
    fn bad_lines_name_the_file_the_line_and_what_was_expected() {
        let cases = [
            ("frames 2\nkey Space\n", "s.txt:2: expected `key NAME`"),
            ("frames 0\n", "s.txt:1: expected `frames N`"),
            ("frames two\n", "s.txt:1: expected `frames N`"),
            ("\n# c\nscreenshot\n", "s.txt:3: expected `screenshot PATH`"),
            ("orbit 30\n", "s.txt:1: expected `orbit AZ,EL`"),
            ("orbit 0,95\n", "s.txt:1: expected `orbit AZ,EL`"),
            ("quit now\n", "s.txt:1: expected `quit` alone"),
            ("size 64\n", "s.txt:1: expected `size WxH`"),
            ("size 0x10\n", "s.txt:1: expected `size WxH`"),
            (
                "jump 3\n",
                "s.txt:1: expected key, frames, screenshot, orbit, size, pick, measure, locate, clip, filter, count, click or quit, got \"jump\"",
            ),
            ("pick 3\n", "s.txt:1: expected `pick X Y`"),
            ("measure distance 1 2 3 4 5 6\n", "s.txt:1: `measure distance` takes 2 pixels, got 3"),
            ("measure area 1 2 3 4\n", "s.txt:1: `measure area` takes at least 3 pixels, got 2"),
            ("measure volume 1 2 3 4\n", "s.txt:1: expected `measure distance|height"),
            ("measure polyline 1 2 3\n", "s.txt:1: expected pixel pairs"),
            ("clip box 1 2 3\n", "s.txt:1: expected `clip box X0 Y0 Z0 X1 Y1 Z1`"),
            ("clip oriented 0 0 0 -1 1 1 0\n", "s.txt:1: clip box: centre"),
            ("clip sideways\n", "s.txt:1: expected `clip box|oriented"),
            ("filter hide 256\n", "s.txt:1: expected classes 0-255"),
            ("filter none\n", "s.txt:1: expected `filter hide|show|only"),
            ("locate 1 2\n", "s.txt:1: expected `locate X Y Z`"),
            ("count 3\n", "s.txt:1: expected `count` alone"),
        ];
        for (text, expected) in cases {
            let e = Script::parse(text, Path::new("s.txt")).unwrap_err();
            assert!(format!("{e:#}").starts_with(expected), "{text:?}: {e:#}");
        }
    }

    #[test]
    fn the_runner_renders_frames_between_keys_and_quits_at_the_end() {
        let s = Script::parse(
            "key m\nframes 2\nscreenshot a.png\norbit 1,2\nsize 8x9\npick 3 4\n",
            Path::new("s"),
        )
        .expect("valid");
        let mut r = Runner::new(s);
        assert_eq!(r.step(), Next::Key(ViewerKey::Char('m')));
        assert_eq!(r.step(), Next::Frame(None));
        assert_eq!(r.step(), Next::Frame(None));
        assert_eq!(r.step(), Next::Frame(Some(PathBuf::from("a.png"))));
        assert_eq!(r.step(), Next::Orbit(1.0, 2.0));
        assert_eq!(r.step(), Next::Size(8, 9));
        assert_eq!(r.step(), Next::Tool(Tool::Pick(3, 4)));
        assert_eq!(r.step(), Next::Quit);
        assert_eq!(r.step(), Next::Quit);
        let mut q = Runner::new(Script::parse("quit\nframes 5\n", Path::new("s")).expect("ok"));
        assert_eq!(q.step(), Next::Quit);
        assert_eq!(q.step(), Next::Quit);
    }

    #[test]
    fn camera_files_must_be_scene_files() {
        assert!(check_camera_file(Path::new("c.toml")).is_ok());
        assert!(check_camera_file(Path::new("c.json")).is_ok());
        let e = check_camera_file(Path::new("c.txt")).unwrap_err();
        assert!(format!("{e}").contains("c.txt"));
    }
}
