//! A rendered frame read back from the GPU: what metrics compare.

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
