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
//! quit                   # (the viewer also quits at the end of the script)
//! ```

use std::path::{Path, PathBuf};

use anyhow::{bail, Context as _, Result};
use winit::keyboard::{Key, NamedKey};

use crate::scene::camera::parse_floats;

/// A key the viewer handles.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ViewerKey {
    /// A letter or digit, lowercase.
    Char(char),
    Tab,
    F11,
    Escape,
}

impl ViewerKey {
    /// Parses a script key name: one letter or digit (any case), `[`, `]`, `,` or `.`, `Tab`, `F11`,
    /// `Esc` or `Escape` (names in any case).
    pub fn parse(name: &str) -> Option<Self> {
        let mut chars = name.chars();
        match (chars.next(), chars.next()) {
            (Some(c), None) if c.is_ascii_alphanumeric() || "[],.".contains(c) => {
                return Some(Self::Char(c.to_ascii_lowercase()))
            }
            _ => {}
        }
        match name.to_ascii_lowercase().as_str() {
            "tab" => Some(Self::Tab),
            "f11" => Some(Self::F11),
            "esc" | "escape" => Some(Self::Escape),
            _ => None,
        }
    }

    /// The viewer key of a winit key event, if it is one.
    pub fn from_winit(key: &Key) -> Option<Self> {
        match key.as_ref() {
            Key::Named(NamedKey::Tab) => Some(Self::Tab),
            Key::Named(NamedKey::F11) => Some(Self::F11),
            Key::Named(NamedKey::Escape) => Some(Self::Escape),
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
    Quit,
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
            format!("expected `key NAME` with NAME a letter, a digit, [, ], Tab, F11 or Esc, got {arg:?}")
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
        _ => Err(format!(
            "expected key, frames, screenshot, orbit, size or quit, got {command:?}"
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
            ViewerKey::from_winit(&Key::Character("K".into())),
            Some(ViewerKey::Char('k'))
        );
        assert_eq!(
            ViewerKey::from_winit(&Key::Named(NamedKey::Tab)),
            Some(ViewerKey::Tab)
        );
        assert_eq!(ViewerKey::from_winit(&Key::Named(NamedKey::F1)), None);
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
                "s.txt:1: expected key, frames, screenshot, orbit, size or quit, got \"jump\"",
            ),
        ];
        for (text, expected) in cases {
            let e = Script::parse(text, Path::new("s.txt")).unwrap_err();
            assert!(format!("{e:#}").starts_with(expected), "{text:?}: {e:#}");
        }
    }

    #[test]
    fn the_runner_renders_frames_between_keys_and_quits_at_the_end() {
        let s = Script::parse(
            "key m\nframes 2\nscreenshot a.png\norbit 1,2\nsize 8x9\n",
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
