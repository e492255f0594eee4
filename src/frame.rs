//! A rendered frame read back from the GPU (what metrics compare), its PNG writer and the
//! image size every front end parses.

use std::path::Path;

/// Largest image edge the renderer accepts (keeps lavapipe tests and typos bounded).
pub const MAX_EDGE: u32 = 8192;

/// An image size, each edge in 1..=`MAX_EDGE`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Size {
    pub width: u32,
    pub height: u32,
}

impl Size {
    /// Parses `WxH` (`x` or `X`, spaces around the numbers allowed).
    pub fn parse(s: &str) -> Result<Size, String> {
        let expected =
            || format!("size '{s}': expected WxH with each edge in 1..={MAX_EDGE}, e.g. 1024x768");
        let (w, h) = s.split_once(['x', 'X']).ok_or_else(expected)?;
        let edge = |t: &str| {
            t.trim()
                .parse::<u32>()
                .ok()
                .filter(|v| (1..=MAX_EDGE).contains(v))
        };
        match (edge(w), edge(h)) {
            (Some(width), Some(height)) => Ok(Size { width, height }),
            _ => Err(expected()),
        }
    }

    /// `(width, height)`.
    pub fn pair(self) -> (u32, u32) {
        (self.width, self.height)
    }
}

/// One frame of a method (or of the ground truth), all planes `width * height`, row-major,
/// row 0 at the top of the image.
#[derive(Clone, Debug, PartialEq)]
pub struct Frame {
    pub width: u32,
    pub height: u32,
    /// sRGB-encoded lit color, alpha 255 where covered, 0 where empty (255 everywhere when the
    /// renderer composited an opaque background, `post::Background`).
    pub color: Vec<[u8; 4]>,
    /// Linear view-space depth (distance along the view direction, > 0) where covered,
    /// `f32::INFINITY` where empty.
    pub depth: Vec<f32>,
    /// Unit view-space normals where the method produces a normal map, `[0,0,0]` where empty.
    pub normal: Option<Vec<[f32; 3]>>,
}

impl Frame {
    pub fn pixels(&self) -> usize {
        self.width as usize * self.height as usize
    }

    /// Coverage mask: a pixel is covered when the method wrote a finite depth to it.
    pub fn covered(&self, i: usize) -> bool {
        self.depth[i].is_finite()
    }
}

/// The channels of a frame's color a PNG keeps.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Channels {
    /// Red, green and blue: an opaque image, alpha dropped (what a window shows).
    Rgb,
    /// Red, green, blue and alpha as stored.
    Rgba,
}

/// Writes `frame`'s color plane to `path` as a PNG of `channels`; the caller names the file in
/// its error.
pub fn write_png(path: &Path, frame: &Frame, channels: Channels) -> image::ImageResult<()> {
    let (w, h) = (frame.width, frame.height);
    match channels {
        Channels::Rgb => {
            let rgb: Vec<u8> = frame
                .color
                .iter()
                .flat_map(|p| [p[0], p[1], p[2]])
                .collect();
            image::save_buffer(path, &rgb, w, h, image::ExtendedColorType::Rgb8)
        }
        Channels::Rgba => image::save_buffer(
            path,
            bytemuck::cast_slice(&frame.color),
            w,
            h,
            image::ExtendedColorType::Rgba8,
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_parse_within_the_edge_bounds() {
        assert_eq!(Size::parse("640x480").map(Size::pair), Ok((640, 480)));
        assert_eq!(Size::parse(" 8 X 8192 ").map(Size::pair), Ok((8, 8192)));
        for bad in ["64", "0x10", "10x0", "8193x1", "axb", "-1x4", "1x2x3", ""] {
            let e = Size::parse(bad).unwrap_err();
            assert!(
                e.contains(&format!("size '{bad}'")) && e.contains("expected WxH"),
                "{e}"
            );
        }
    }
}
