//! How a scene looks around its points: eye-dome lighting parameters and the background
//! colour. Parsed from the command line and scene files; the post stage turns them into a pass.

use std::fmt;

use serde::{Deserialize, Serialize};

use crate::layout::EDL_NEIGHBOURS;

// `PostParams` holds the offsets of exactly eight neighbours.
const _: () = assert!(EDL_NEIGHBOURS == 8);

/// Potree's default EDL strength.
pub const DEFAULT_STRENGTH: f32 = 1.0;
/// Potree's default EDL radius in pixels.
pub const DEFAULT_RADIUS: f32 = 1.4;
/// Largest EDL strength accepted.
pub const MAX_STRENGTH: f32 = 100.0;
/// Smallest and largest EDL radius accepted, in pixels.
pub const RADIUS_RANGE: (f32, f32) = (1.0, 64.0);
/// `--edl` without a value: the defaults, written as the flag takes them.
pub const EDL_DEFAULT_ARG: &str = "1,1.4";

/// Eye-dome lighting parameters.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "EdlFields")]
pub struct Edl {
    /// Scales the darkening: shade = exp(-300 strength mean response).
    pub strength: f32,
    /// Distance of the neighbours from the pixel, in pixels.
    pub radius: f32,
}

impl Default for Edl {
    fn default() -> Self {
        Self {
            strength: DEFAULT_STRENGTH,
            radius: DEFAULT_RADIUS,
        }
    }
}

/// How a scene file spells `edl = { strength = 1.0, radius = 1.4 }` (both optional).
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct EdlFields {
    strength: Option<f32>,
    radius: Option<f32>,
}

impl TryFrom<EdlFields> for Edl {
    type Error = String;

    fn try_from(f: EdlFields) -> Result<Self, String> {
        Edl::new(
            f.strength.unwrap_or(DEFAULT_STRENGTH),
            f.radius.unwrap_or(DEFAULT_RADIUS),
        )
    }
}

impl Edl {
    /// Checked parameters: strength in 0..=`MAX_STRENGTH`, radius in `RADIUS_RANGE`.
    pub fn new(strength: f32, radius: f32) -> Result<Self, String> {
        if !(0.0..=MAX_STRENGTH).contains(&strength) {
            return Err(format!(
                "EDL strength {strength} is outside 0..={MAX_STRENGTH}"
            ));
        }
        let (lo, hi) = RADIUS_RANGE;
        if !(lo..=hi).contains(&radius) {
            return Err(format!("EDL radius {radius} is outside {lo}..={hi} pixels"));
        }
        Ok(Self { strength, radius })
    }

    /// Parses `STRENGTH` or `STRENGTH,RADIUS` (the `--edl` value; the command line names the
    /// value in its error).
    pub fn parse(s: &str) -> Result<Self, String> {
        let expected = || {
            format!(
                "expected STRENGTH[,RADIUS], numbers with STRENGTH in 0..={MAX_STRENGTH} and \
                 RADIUS in {}..={} pixels (default {EDL_DEFAULT_ARG})",
                RADIUS_RANGE.0, RADIUS_RANGE.1
            )
        };
        let number = |t: &str| t.trim().parse::<f32>().map_err(|_| expected());
        let (strength, radius) = match s.split_once(',') {
            Some((a, b)) => (number(a)?, number(b)?),
            None => (number(s)?, DEFAULT_RADIUS),
        };
        Self::new(strength, radius)
    }

    /// The integer pixel offsets of the neighbours: `radius` pixels away in the directions
    /// 2πi/N (Potree's neighbour circle), rounded half up to the pixel whose area the point
    /// falls in (the nearest-neighbour lookup of the references).
    pub fn offsets(&self) -> [[i32; 2]; EDL_NEIGHBOURS as usize] {
        std::array::from_fn(|i| {
            let angle = std::f64::consts::TAU * i as f64 / f64::from(EDL_NEIGHBOURS);
            let r = f64::from(self.radius);
            [angle.cos(), angle.sin()].map(|c| (r * c + 0.5).floor() as i32)
        })
    }
}

/// What fills the pixels no method covered.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(try_from = "String", into = "String")]
pub enum Background {
    /// Left as the method wrote them (alpha 0).
    Transparent,
    /// An opaque sRGB color.
    Color([u8; 3]),
}

impl Background {
    /// The default of `render` and `view`: opaque black, what the evaluation composites over
    /// and the viewer showed before backgrounds existed.
    pub const DEFAULT: Background = Background::Color([0, 0, 0]);

    /// Parses `#rrggbb`, `r,g,b` (0-255), `black`, `white`, `grey`/`gray` or `transparent` (the
    /// caller names the value in its error).
    pub fn parse(s: &str) -> Result<Self, String> {
        let t = s.trim();
        let rgb = match t.to_ascii_lowercase().as_str() {
            "transparent" => return Ok(Background::Transparent),
            "black" => Some([0, 0, 0]),
            "white" => Some([255, 255, 255]),
            "grey" | "gray" => Some([128, 128, 128]),
            _ => match t.strip_prefix('#') {
                Some(hex) if hex.len() == 6 && hex.chars().all(|c| c.is_ascii_hexdigit()) => {
                    let byte = |i: usize| u8::from_str_radix(&hex[i..i + 2], 16).ok();
                    byte(0)
                        .zip(byte(2))
                        .zip(byte(4))
                        .map(|((r, g), b)| [r, g, b])
                }
                Some(_) => None,
                None => {
                    let mut parts = t.split(',').map(|p| p.trim().parse::<u8>().ok());
                    match (parts.next(), parts.next(), parts.next(), parts.next()) {
                        (Some(Some(r)), Some(Some(g)), Some(Some(b)), None) => Some([r, g, b]),
                        _ => None,
                    }
                }
            },
        };
        rgb.map(Background::Color).ok_or_else(|| {
            let names = ["black", "white", "grey", "gray", "transparent"];
            format!(
                "expected a color as #rrggbb, r,g,b (each 0-255), black, white or grey, or \
                 transparent{}",
                crate::suggest::did_you_mean(t, names)
            )
        })
    }
}

impl fmt::Display for Background {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Background::Transparent => f.write_str("transparent"),
            Background::Color([r, g, b]) => write!(f, "#{r:02x}{g:02x}{b:02x}"),
        }
    }
}

impl TryFrom<String> for Background {
    type Error = String;

    fn try_from(s: String) -> Result<Self, String> {
        Background::parse(&s).map_err(|e| format!("background '{s}': {e}"))
    }
}

impl From<Background> for String {
    fn from(b: Background) -> String {
        b.to_string()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn edl_values_parse_with_defaults_and_ranges() {
        assert_eq!(Edl::parse(EDL_DEFAULT_ARG), Ok(Edl::default()));
        assert_eq!(Edl::parse("2.5"), Edl::new(2.5, DEFAULT_RADIUS));
        assert_eq!(Edl::parse(" 0.5 , 3 "), Edl::new(0.5, 3.0));
        let e = Edl::parse("x").unwrap_err();
        assert!(e.contains("expected STRENGTH[,RADIUS]"), "{e}");
        let e = Edl::parse("1,0.5").unwrap_err();
        assert!(e.contains("radius 0.5 is outside 1..=64"), "{e}");
        let e = Edl::parse("-1").unwrap_err();
        assert!(e.contains("strength -1 is outside 0..=100"), "{e}");
        assert!(Edl::parse("NaN").is_err() && Edl::parse("1,2,3").is_err());
    }

    #[test]
    fn a_mistyped_background_name_gets_the_closest() {
        let expected = "expected a color as #rrggbb, r,g,b (each 0-255), black, white or grey, \
                        or transparent";
        assert_eq!(
            Background::parse("whte"),
            Err(format!("{expected}; did you mean 'white'?"))
        );
        assert_eq!(
            Background::parse("transparnet"),
            Err(format!("{expected}; did you mean 'transparent'?"))
        );
        assert_eq!(Background::parse("pink"), Err(expected.to_owned()));
        assert_eq!(Background::parse("1,2"), Err(expected.to_owned()));
    }

    #[test]
    fn edl_neighbours_ring_the_pixel_at_the_radius() {
        // Potree's default radius 1.4 picks the 8-connected ring, counter-clockwise from +x.
        let ring = [
            [1, 0],
            [1, 1],
            [0, 1],
            [-1, 1],
            [-1, 0],
            [-1, -1],
            [0, -1],
            [1, -1],
        ];
        assert_eq!(Edl::default().offsets(), ring);
        assert_eq!(
            Edl::new(1.0, 3.0).expect("valid").offsets(),
            [
                [3, 0],
                [2, 2],
                [0, 3],
                [-2, 2],
                [-3, 0],
                [-2, -2],
                [0, -3],
                [2, -2]
            ]
        );
    }

    #[test]
    fn backgrounds_parse_as_hex_triples_and_names() {
        let c = |r, g, b| Ok(Background::Color([r, g, b]));
        assert_eq!(Background::parse("#FF8000"), c(255, 128, 0));
        assert_eq!(Background::parse("12, 34,56"), c(12, 34, 56));
        assert_eq!(Background::parse("White"), c(255, 255, 255));
        assert_eq!(Background::parse("gray"), c(128, 128, 128));
        assert_eq!(
            Background::parse("transparent"),
            Ok(Background::Transparent)
        );
        for bad in [
            "#12345", "#12345g", "#+f+f+f", "#ééé", "1,2", "256,0,0", "pink", "",
        ] {
            let e = Background::try_from(bad.to_string()).unwrap_err();
            assert!(
                e.contains(&format!("background '{bad}'")) && e.contains("#rrggbb, r,g,b"),
                "{e}"
            );
        }
        for b in [
            Background::DEFAULT,
            Background::Transparent,
            Background::Color([1, 2, 250]),
        ] {
            assert_eq!(Background::parse(&b.to_string()), Ok(b));
        }
    }
}
