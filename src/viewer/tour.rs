//! A scripted tour as the viewer runs it: the steps up to the next frame, applied through the
//! same handlers as keys and clicks; a `size` step renders until the window has its size.

use anyhow::{bail, Result};
use winit::dpi::PhysicalSize;

use super::script::{Next, Tool};
use super::Viewer;

/// Frames a script's `size` step waits for the window to take its size.
const RESIZE_FRAMES: u32 = 500;

impl Viewer {
    /// Runs script steps up to the next frame; returns false when the script is over.
    pub(super) fn run_script(&mut self) -> Result<bool> {
        if let (Some((size, waited)), Some(gpu)) = (self.resizing.as_mut(), self.gpu.as_ref()) {
            let now = gpu.window.inner_size();
            if now != *size {
                // The window system resizes asynchronously: keep rendering meanwhile.
                *waited += 1;
                if *waited > RESIZE_FRAMES {
                    bail!(
                        "the window did not resize to {}x{} within {RESIZE_FRAMES} frames (it is {}x{})",
                        size.width,
                        size.height,
                        now.width,
                        now.height
                    );
                }
                return Ok(true);
            }
            self.resizing = None;
        }
        while let Some(runner) = self.script.as_mut() {
            match runner.step() {
                Next::Key(k) => self.press(k)?,
                Next::Orbit(az, el) => self.orbit.set_angles(az, el),
                Next::Size(w, h) => {
                    let size = PhysicalSize::new(w, h);
                    if let Some(gpu) = &self.gpu {
                        // `None`: the size is applied later, reported by a `Resized` event.
                        let _ = gpu.window.request_inner_size(size);
                    }
                    self.resizing = Some((size, 0));
                    return self.run_script();
                }
                Next::Frame(shot) => {
                    self.screenshots.extend(shot);
                    return Ok(true);
                }
                Next::Tool(Tool::Click(x, y)) => {
                    // A legend line toggles its class at once; a pick waits for a frame.
                    if self.click(x, y)? {
                        return Ok(true);
                    }
                }
                Next::Tool(tool) if tool.needs_frame() => {
                    // Runs on the next frame's depth.
                    self.tools.requests.push(tool);
                    return Ok(true);
                }
                Next::Tool(tool) => self.tool_now(tool)?,
                Next::Quit => return Ok(false),
            }
            if self.quit {
                return Ok(false);
            }
        }
        Ok(true)
    }
}
