//! Scene files (TOML or JSON): a camera pose, lights and post-processing.
//!
//! ```toml
//! up = "z"                 # x | y | z | -x | -y | -z (default: from the file format)
//! edl = { strength = 1.0, radius = 1.4 }   # eye-dome lighting (both optional)
//! background = "#202020"   # #rrggbb | r,g,b | black | white | grey | transparent
//! color_by = "intensity"   # any field `surfel info` lists (default: rgb, else none)
//! hidden_classes = [7, 18] # classification classes not drawn
//! [camera]
//! orbit = [30.0, 15.0]     # or: eye = [x, y, z]  target = [x, y, z] (file coordinates)
//! [clip]                   # a clipping box in file coordinates (the viewer's `B`)
//! centre = [512345.0, 4123456.0, 250.0]
//! half = [20.0, 10.0, 30.0]
//! rotation = [30.0, 0.0, 0.0]   # yaw, pitch, roll in degrees (default: axis-aligned)
//! keep = "inside"          # inside | outside
//! [[bookmarks]]            # the viewer's camera bookmarks (Ctrl+1-9 store, 1-9 recall)
//! slot = 1
//! eye = [512300.0, 4123400.0, 300.0]
//! target = [512345.0, 4123456.0, 250.0]
//! [[lights]]
//! kind = "static"          # camera | static | orbit
//! position = [1.0, 2.0, 3.0]
//! color = [1.0, 0.9, 0.8]
//! [[inputs]]               # more inputs beside the command line's file (`scene::compose`)
//! path = "buddha.obj"      # relative to this file
//! as = "triangles"         # triangles | points (default: triangles when it has faces)
//! translate = [0.3, 0.0, 0.0]
//! scale = 0.2
//! ```

use std::path::Path;

use anyhow::{bail, Context as _, Result};
use serde::{Deserialize, Serialize};

use super::camera::{Pose, Up};
use super::clip::{ClipBox, Filter};
use super::compose::SceneInput;
use super::lights::Light;
use crate::scene::appearance::{Background, Edl};

/// The parsed file.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneFile {
    /// The up axis, overriding the input format's convention.
    pub up: Option<Up>,
    pub camera: Option<Pose>,
    #[serde(default)]
    pub lights: Vec<Light>,
    /// Eye-dome lighting with these parameters.
    pub edl: Option<Edl>,
    /// The background color (or `transparent`).
    pub background: Option<Background>,
    /// The field to color by (`--color-by`).
    pub color_by: Option<String>,
    /// More inputs merged into the scene (hybrid scenes, 000 §5.2).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub inputs: Vec<SceneInput>,
    /// Classification classes not drawn.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub hidden_classes: Vec<u8>,
    /// The clipping box.
    pub clip: Option<ClipBox>,
    /// Camera bookmarks, in file coordinates.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub bookmarks: Vec<Bookmark>,
}

/// A stored camera: slot 1-9, eye and target in the file's coordinates.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Bookmark {
    pub slot: u8,
    pub eye: [f64; 3],
    pub target: [f64; 3],
}

impl SceneFile {
    /// The clipping box and hidden classes the file sets.
    pub fn filter(&self) -> Filter {
        Filter {
            clip: self.clip,
            hidden: crate::scene::clip::Classes::from_list(&self.hidden_classes),
        }
    }

    /// Reads `path` as TOML (`.toml`) or JSON (`.json`).
    pub fn load(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path)
            .with_context(|| format!("{}: cannot read scene file", path.display()))?;
        let mut file = Self::parse(&text, path)?;
        let dir = path.parent().unwrap_or(Path::new(""));
        for input in &mut file.inputs {
            input.path = dir.join(&input.path);
        }
        Ok(file)
    }

    /// Parses `text`; `path` names the format and appears in errors, with the line where the
    /// parser found the problem: `FILE: line N: invalid scene file: MESSAGE`.
    pub fn parse(text: &str, path: &Path) -> Result<Self> {
        let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("");
        let invalid = |line: Option<usize>, message: &str| {
            let at = line.map_or(String::new(), |n| format!("line {n}: "));
            anyhow::anyhow!("{}: {at}invalid scene file: {message}", path.display())
        };
        let file: Self = match ext {
            "toml" => toml::from_str(text).map_err(|e| {
                let bytes = text.as_bytes();
                let line = e.span().map(|span| {
                    let before = &bytes[..span.start.min(bytes.len())];
                    before.iter().filter(|&&b| b == b'\n').count() + 1
                });
                invalid(line, e.message().trim_end())
            })?,
            "json" => serde_json::from_str(text).map_err(|e| {
                let message = e.to_string();
                let at = format!(" at line {} column {}", e.line(), e.column());
                let message = message.strip_suffix(&at).unwrap_or(&message);
                invalid((e.line() > 0).then_some(e.line()), message)
            })?,
            _ => bail!("{}: scene files must end in .toml or .json", path.display()),
        };
        file.check()
            .map_err(|e| anyhow::anyhow!("{}: invalid scene file: {e}", path.display()))?;
        Ok(file)
    }

    /// Refuses values that parse but render nothing defined: a camera [`Pose::check`]
    /// refuses, a light with a non-finite position or a colour that is negative or not finite,
    /// an input scale outside 10⁻⁶..10⁶ or a translation that is not finite.
    fn check(&self) -> Result<(), String> {
        if let Some(pose) = &self.camera {
            pose.check()?;
        }
        if let Some(clip) = &self.clip {
            clip.check()?;
        }
        for b in &self.bookmarks {
            if !(1..=9).contains(&b.slot) {
                return Err(format!("bookmark slot {} must be 1 to 9", b.slot));
            }
            Pose::LookAt {
                eye: b.eye,
                target: b.target,
            }
            .check()
            .map_err(|e| format!("bookmark {}: {e}", b.slot))?;
        }
        for (i, light) in self.lights.iter().enumerate() {
            if !light.position.iter().all(|v| v.is_finite())
                || !light.color.iter().all(|c| c.is_finite() && *c >= 0.0)
            {
                return Err(format!(
                    "light {i}: position {:?} must be finite and color {:?} finite and not negative",
                    light.position, light.color
                ));
            }
        }
        for input in &self.inputs {
            let name = input.path.display();
            if let Some(scale) = input.scale {
                if !(1e-6..=1e6).contains(&scale) {
                    return Err(format!(
                        "input {name}: scale {scale} is outside 1e-6 to 1e6"
                    ));
                }
            }
            if let Some(t) = input.translate {
                if !t.iter().all(|v| v.is_finite()) {
                    return Err(format!("input {name}: translate {t:?} must be finite"));
                }
            }
        }
        Ok(())
    }

    /// Writes the file as TOML (`.toml`) or JSON (`.json`).
    pub fn save(&self, path: &Path) -> Result<()> {
        let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("");
        let text = match ext {
            "toml" => toml::to_string(self)
                .with_context(|| format!("{}: cannot encode scene file", path.display()))?,
            "json" => serde_json::to_string_pretty(self)
                .with_context(|| format!("{}: cannot encode scene file", path.display()))?,
            _ => bail!("{}: scene files must end in .toml or .json", path.display()),
        };
        std::fs::write(path, text)
            .with_context(|| format!("{}: cannot write scene file", path.display()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::lights::LightKind;

    #[test]
    fn parses_toml_and_json_scene_files() {
        let t = SceneFile::parse(
            "[camera]\norbit = [30.0, 15.0]\n[[lights]]\nkind = \"static\"\nposition = [1.0, 2.0, 3.0]\n",
            Path::new("s.toml"),
        )
        .expect("valid toml");
        assert_eq!(
            t.camera,
            Some(Pose::Orbit {
                orbit: [30.0, 15.0],
                distance: 1.0
            })
        );
        assert_eq!(t.lights[0].kind, LightKind::Static);
        assert_eq!(t.lights[0].color, [1.0; 3]);
        let j = SceneFile::parse(
            r#"{"camera": {"eye": [0, 0, 5], "target": [0, 0, 0]}, "lights": []}"#,
            Path::new("s.json"),
        )
        .expect("valid json");
        assert!(matches!(j.camera, Some(Pose::LookAt { .. })));
        assert_eq!(j.up, None);
        let u = SceneFile::parse("up = \"-z\"\n", Path::new("u.toml")).expect("valid up");
        assert_eq!(u.up, Some(Up::NegZ));
        let j = SceneFile::parse(r#"{"up": "x"}"#, Path::new("u.json")).expect("valid up");
        assert_eq!(j.up, Some(Up::X));
        let c = SceneFile::parse("color_by = \"Deviation\"\n", Path::new("c.toml")).expect("color");
        assert_eq!(c.color_by.as_deref(), Some("Deviation"));
    }

    #[test]
    fn parses_post_processing_with_defaults_and_checks_it() {
        use crate::scene::appearance::{Background, Edl};
        let t = SceneFile::parse(
            "edl = { radius = 3 }\nbackground = \"#102030\"\n",
            Path::new("s.toml"),
        )
        .expect("valid post-processing");
        assert_eq!(t.edl, Some(Edl::new(1.0, 3.0).expect("valid")));
        assert_eq!(t.background, Some(Background::Color([16, 32, 48])));
        let j = SceneFile::parse(
            r#"{"edl": {}, "background": "transparent"}"#,
            Path::new("s.json"),
        )
        .expect("valid post-processing");
        assert_eq!(j.edl, Some(Edl::default()));
        assert_eq!(j.background, Some(Background::Transparent));
        let e = SceneFile::parse("edl = { strength = -2 }\n", Path::new("e.toml")).unwrap_err();
        let e = format!("{e:#}");
        assert!(
            e.contains("e.toml") && e.contains("strength -2 is outside"),
            "{e}"
        );
        let e = SceneFile::parse("edl = { size = 2 }\n", Path::new("e.toml")).unwrap_err();
        assert!(format!("{e:#}").contains("size"), "{e:#}");
        let e = SceneFile::parse("background = \"pink\"\n", Path::new("b.toml")).unwrap_err();
        let e = format!("{e:#}");
        assert!(
            e.contains("b.toml") && e.contains("background 'pink'"),
            "{e}"
        );
    }

    #[test]
    fn rejects_values_that_render_nothing_defined() {
        for (text, expected) in [
            (
                "[camera]\neye = [0, 0, 1]\ntarget = [0, 0, 1]\n",
                "same point",
            ),
            (
                "[camera]\neye = [0, nan, 1]\ntarget = [0, 0, 0]\n",
                "must be finite",
            ),
            ("[camera]\norbit = [inf, 0]\n", "must be finite"),
            (
                "[camera]\norbit = [0, 0]\ndistance = 0\n",
                "distance 0 positive",
            ),
            (
                "[[lights]]\nkind = \"static\"\nposition = [nan, 0, 0]\n",
                "light 0",
            ),
            (
                "[[lights]]\nkind = \"camera\"\ncolor = [1, -1, 1]\n",
                "light 0",
            ),
            ("[[inputs]]\npath = \"a.ply\"\nscale = nan\n", "scale NaN"),
            (
                "[[inputs]]\npath = \"a.ply\"\nscale = 1e30\n",
                "outside 1e-6 to 1e6",
            ),
            (
                "[[inputs]]\npath = \"a.ply\"\ntranslate = [0, inf, 0]\n",
                "must be finite",
            ),
        ] {
            let e = format!(
                "{:#}",
                SceneFile::parse(text, Path::new("s.toml")).unwrap_err()
            );
            assert!(
                e.starts_with("s.toml: invalid scene file: ") && e.contains(expected),
                "{text}: {e}"
            );
        }
    }

    #[test]
    fn rejects_unknown_keys_and_formats() {
        let e = SceneFile::parse("[camra]\n", Path::new("bad.toml")).unwrap_err();
        assert!(format!("{e:#}").contains("bad.toml"));
        assert!(SceneFile::parse("{}", Path::new("s.yaml")).is_err());
        let e = SceneFile::parse("up = \"w\"\n", Path::new("up.toml")).unwrap_err();
        assert!(format!("{e:#}").contains("`w`"), "{e:#}");
    }

    #[test]
    fn a_camera_of_neither_form_is_refused_with_the_forms_and_the_line() {
        use crate::scene::camera::POSE_FORMS;
        let error = |text: &str, name: &str| {
            format!("{:#}", SceneFile::parse(text, Path::new(name)).unwrap_err())
        };
        for (text, line, found) in [
            (
                "up = \"z\"\n[camera]\neye = [0, 0, 5]\n",
                2,
                "`eye` without `target`",
            ),
            (
                "[camera]\ntarget = [0, 0, 5]\n",
                1,
                "`target` without `eye`",
            ),
            (
                "[camera]\norbit = [30, 15]\neye = [0, 0, 5]\ntarget = [0, 0, 0]\n",
                1,
                "`orbit` with `eye` or `target`",
            ),
            (
                "[camera]\neye = [0, 0, 5]\ntarget = [0, 0, 0]\ndistance = 2\n",
                1,
                "`distance` with `eye` and `target`",
            ),
            ("[camera]\ndistance = 2\n", 1, "`distance` without `orbit`"),
            ("camera = {}\n", 1, "an empty table"),
        ] {
            assert_eq!(
                error(text, "s.toml"),
                format!(
                    "s.toml: line {line}: invalid scene file: camera: {POSE_FORMS}; found {found}"
                ),
                "{text}"
            );
        }
        assert_eq!(
            error(
                "{\n  \"camera\": {\"orbit\": [30, 15], \"eye\": [0, 0, 1]},\n  \"up\": \"z\"\n}",
                "s.json"
            ),
            format!(
                "s.json: line 2: invalid scene file: camera: {POSE_FORMS}; found `orbit` with \
                 `eye` or `target`"
            )
        );
        assert_eq!(
            error("[camera]\norbt = [30, 15]\n", "s.toml"),
            "s.toml: line 2: invalid scene file: unknown field `orbt`, expected one of `orbit`, \
             `distance`, `eye`, `target`"
        );
        assert_eq!(
            error("[camera]\norbit = [30]\n", "s.toml"),
            "s.toml: line 2: invalid scene file: invalid length 1, expected an array of length 2"
        );
        assert_eq!(
            POSE_FORMS,
            "expected `orbit = [AZ, EL]` (degrees; `distance = D` scales the framing distance, \
             default 1) or `eye = [X, Y, Z]` with `target = [X, Y, Z]`"
        );
    }

    #[test]
    fn inputs_resolve_against_the_scene_file_and_are_checked() {
        use crate::scene::compose::Role;
        let dir = std::env::temp_dir().join(format!("surfel-scene-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("hybrid.toml");
        std::fs::write(
            &path,
            "[[inputs]]\npath = \"meshes/buddha.obj\"\nas = \"points\"\nscale = 0.5\n\
             [[inputs]]\npath = \"/abs/cloud.ply\"\ntranslate = [1.0, 2.0, 3.0]\n",
        )
        .unwrap();
        let file = SceneFile::load(&path).unwrap();
        assert_eq!(file.inputs.len(), 2);
        assert_eq!(file.inputs[0].path, dir.join("meshes/buddha.obj"));
        assert_eq!(
            (file.inputs[0].role, file.inputs[0].scale),
            (Role::Points, Some(0.5))
        );
        assert_eq!(file.inputs[1].path, Path::new("/abs/cloud.ply"));
        assert_eq!(file.inputs[1].role, Role::Auto);
        assert_eq!(file.inputs[1].translate, Some([1.0, 2.0, 3.0]));
        std::fs::remove_dir_all(&dir).unwrap();
        let e =
            SceneFile::parse("[[inputs]]\npath = \"a.ply\"\nas = \"lines\"\n", &path).unwrap_err();
        assert!(format!("{e:#}").contains("lines"), "{e:#}");
        let e = SceneFile::parse("[[inputs]]\nfile = \"a.ply\"\n", &path).unwrap_err();
        assert!(format!("{e:#}").contains("file"), "{e:#}");
    }
}
