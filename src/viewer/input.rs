//! The mouse: `Pointer` (the cursor, the button dragging, where a click began, Ctrl), drags
//! that orbit and pan, the wheel's zoom, and clicks (a legend line toggles its class, elsewhere
//! the click tool picks).

use anyhow::Result;
use glam::Vec2;
use winit::dpi::PhysicalPosition;
use winit::event::{ElementState, MouseButton, MouseScrollDelta};

use super::script::Tool;
use super::Viewer;

/// Pixels the cursor may move between press and release of a click.
const CLICK_SLOP: f32 = 3.0;

/// The mouse and modifier state.
#[derive(Default)]
pub(super) struct Pointer {
    /// The button held and the cursor's position when it last moved.
    drag: Option<(MouseButton, Vec2)>,
    cursor: Vec2,
    /// Where the left button went down (a release within a few pixels is a click).
    press: Option<Vec2>,
    /// Ctrl is held.
    pub ctrl: bool,
}

impl Viewer {
    /// A button went down or up: starts or ends a drag; a left release where the button went
    /// down is a click.
    pub(super) fn mouse_input(&mut self, button: MouseButton, state: ElementState) -> Result<()> {
        let pointer = &mut self.pointer;
        let pressed = state == ElementState::Pressed;
        pointer.drag = pressed.then_some((button, pointer.cursor));
        match (button, pressed, pointer.press) {
            (MouseButton::Left, true, _) => {
                pointer.press = Some(pointer.cursor);
                Ok(())
            }
            (MouseButton::Left, false, Some(at)) => {
                pointer.press = None;
                // A release where the button went down is a click, not a drag.
                let cursor = pointer.cursor;
                if (cursor - at).length() <= CLICK_SLOP {
                    self.click(cursor.x as i32, cursor.y as i32).map(|_| ())
                } else {
                    Ok(())
                }
            }
            _ => Ok(()),
        }
    }

    /// The cursor moved: a left drag orbits, any other pans.
    pub(super) fn cursor_moved(&mut self, position: PhysicalPosition<f64>) {
        let p = Vec2::new(position.x as f32, position.y as f32);
        if let Some((button, last)) = self.pointer.drag {
            let d = p - last;
            match button {
                MouseButton::Left => self.orbit.turn(d),
                _ => {
                    let h = self
                        .gpu
                        .as_ref()
                        .map_or(1.0, |g| g.swapchain.extent.height as f32);
                    self.orbit.pan(d, h);
                }
            }
            self.pointer.drag = Some((button, p));
        }
        self.pointer.cursor = p;
    }

    /// The wheel zooms, a line at a time (40 pixels a line).
    pub(super) fn mouse_wheel(&mut self, delta: MouseScrollDelta) {
        let lines = match delta {
            MouseScrollDelta::LineDelta(_, y) => y,
            MouseScrollDelta::PixelDelta(p) => p.y as f32 / 40.0,
        };
        self.orbit.zoom(lines);
    }

    /// A left click at a window pixel: on a legend line of the HUD as it stands it toggles the
    /// class, elsewhere the current tool picks there on the next frame's depth (then it returns
    /// true).
    pub(super) fn click(&mut self, x: i32, y: i32) -> Result<bool> {
        if self.hud.dirty {
            self.refresh_hud();
        }
        if let Some(class) = self.hud.legend_class_at(x as f32, y as f32) {
            match u8::try_from(class) {
                Ok(c) => self.toggle_class(c)?,
                Err(_) => {
                    self.outcome(Ok("values that are not classes cannot be hidden".into()))?
                }
            }
            return Ok(false);
        }
        self.tools.requests.push(Tool::Click(x, y));
        Ok(true)
    }
}
