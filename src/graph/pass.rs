//! One expression per pass: a compute or draw pass names its shader(s) and bind list; the
//! graph creates the pipeline from that list when it compiles (one pipeline per distinct
//! program), declares the accesses, and records bind, push constants and the launch.
//!
//! ```ignore
//! let binds = Binds::from([
//!     Bind::constants(BINDING_FRAME, frame),
//!     Bind::reads(BINDING_SEGMENTS, segments),
//!     Bind::writes(BINDING_OUTPUT, output),
//! ]);
//! g.compute("family.pass", "family/pass.comp", &binds)
//!     .spec(&[(SPEC_MODE, 1)])
//!     .push(&params)
//!     .dispatch(groups);
//! g.compute("family.again", "family/pass.comp", &binds.with(Bind::writes(BINDING_OUTPUT, other)))
//!     .dispatch(groups);
//! ```

use std::ops::Deref;
use std::sync::Arc;

use anyhow::{Context as _, Result};

use super::bind::{self, Bind};
use super::{Access, BufferId, BufferRange, GraphBuilder, ImageId, Load, PassBuilder, PassContext};
use crate::gpu::pipeline::stages_of;
use crate::gpu::{Binding, Context, GraphicsDesc, Pipeline};

/// A pass's bind list; [`Binds::with`] derives a variant differing in some bindings.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Binds(Vec<Bind>);

impl Binds {
    /// This list with `bind` in place of the entry of the same binding number (appended when
    /// there is none).
    pub fn with(&self, bind: Bind) -> Self {
        let mut binds = self.clone();
        match binds.0.iter_mut().find(|b| b.binding == bind.binding) {
            Some(b) => *b = bind,
            None => binds.0.push(bind),
        }
        binds
    }

    /// Appends `bind`.
    pub fn push(&mut self, bind: Bind) {
        self.0.push(bind);
    }
}

impl Extend<Bind> for Binds {
    fn extend<I: IntoIterator<Item = Bind>>(&mut self, binds: I) {
        self.0.extend(binds);
    }
}

impl<const N: usize> From<[Bind; N]> for Binds {
    fn from(binds: [Bind; N]) -> Self {
        Self(binds.to_vec())
    }
}

impl From<Vec<Bind>> for Binds {
    fn from(binds: Vec<Bind>) -> Self {
        Self(binds)
    }
}

impl Deref for Binds {
    type Target = [Bind];

    fn deref(&self) -> &[Bind] {
        &self.0
    }
}

/// What a pass's pipeline is made of; passes with equal programs share one pipeline.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Program {
    kind: ProgramKind,
    layout: Vec<Binding>,
}

#[derive(Clone, Debug, PartialEq)]
enum ProgramKind {
    Compute {
        shader: String,
        spec: Vec<(u32, u32)>,
    },
    Graphics(GraphicsDesc),
}

impl Program {
    fn create(&self, ctx: &Arc<Context>) -> Result<Pipeline> {
        match &self.kind {
            ProgramKind::Compute { shader, spec } => {
                Pipeline::compute_specialized(ctx, shader, &self.layout, spec)
            }
            ProgramKind::Graphics(desc) => Pipeline::graphics(ctx, desc, &self.layout),
        }
    }
}

/// The pipelines of `programs` (by pass; `None` for passes without one), each distinct
/// program created once.
pub(super) fn create_pipelines<'a>(
    ctx: &Arc<Context>,
    programs: impl Iterator<Item = (&'a str, Option<&'a Program>)>,
) -> Result<Vec<Option<Arc<Pipeline>>>> {
    let mut made: Vec<(&Program, Arc<Pipeline>)> = Vec::new();
    programs
        .map(|(name, program)| {
            let Some(program) = program else {
                return Ok(None);
            };
            if let Some((_, p)) = made.iter().find(|(q, _)| *q == program) {
                return Ok(Some(p.clone()));
            }
            let pipeline = Arc::new(
                program
                    .create(ctx)
                    .with_context(|| format!("the pipeline of pass '{name}'"))?,
            );
            ctx.name_object(pipeline.raw, name);
            ctx.name_object(pipeline.layout, name);
            made.push((program, pipeline.clone()));
            Ok(Some(pipeline))
        })
        .collect()
}

/// The part of a pipeline pass common to compute and draw: accesses, binds, push constants.
struct Common<'g> {
    pass: PassBuilder<'g>,
    binds: Binds,
    push: Vec<u8>,
}

impl<'g> Common<'g> {
    fn new(g: &'g mut GraphBuilder, name: &str, binds: &[Bind]) -> Self {
        Self {
            pass: g.pass(name).binds(binds),
            binds: Binds(binds.to_vec()),
            push: Vec::new(),
        }
    }

    /// Adds the pass with `program`: bind, push, then `launch`.
    fn finish(self, program: Program, launch: impl Fn(&PassContext<'_>) + 'static) {
        let Self {
            mut pass,
            binds,
            push,
        } = self;
        pass.decl().program = Some(program);
        pass.record(move |ctx| {
            let pipeline = ctx.pipeline();
            ctx.bind_all(pipeline, &binds);
            if !push.is_empty() {
                ctx.push(pipeline, &push);
            }
            launch(ctx);
        });
    }
}

/// A compute pass being declared; a `dispatch*` call adds it to the graph.
pub struct ComputePass<'g> {
    common: Common<'g>,
    shader: String,
    spec: Vec<(u32, u32)>,
}

impl<'g> ComputePass<'g> {
    /// Specialization constants `(constant_id, value)` of the shader.
    pub fn spec(mut self, constants: &[(u32, u32)]) -> Self {
        self.spec = constants.to_vec();
        self
    }

    /// Push constants (at most `PUSH_CONSTANT_BYTES`).
    pub fn push(self, value: &impl bytemuck::NoUninit) -> Self {
        self.push_bytes(bytemuck::bytes_of(value))
    }

    /// Push constants as bytes.
    pub fn push_bytes(mut self, bytes: &[u8]) -> Self {
        self.common.push = bytes.to_vec();
        self
    }

    /// Accesses beyond the bind list (e.g. a buffer the pass copies into).
    pub fn declare(mut self, f: impl FnOnce(PassBuilder<'g>) -> PassBuilder<'g>) -> Self {
        self.common.pass = f(self.common.pass);
        self
    }

    fn program(&self) -> Program {
        Program {
            kind: ProgramKind::Compute {
                shader: self.shader.clone(),
                spec: self.spec.clone(),
            },
            layout: bind::compute_layout(&self.common.binds),
        }
    }

    /// `groups` workgroups, folded into rows past `bind::MAX_GROUPS` (`bind::fold_groups`).
    pub fn dispatch(self, groups: u64) {
        let program = self.program();
        self.common
            .finish(program, move |ctx| ctx.dispatch_groups(groups));
    }

    /// An `x` by `y` grid of workgroups.
    pub fn dispatch_grid(self, (x, y): (u32, u32)) {
        let program = self.program();
        self.common
            .finish(program, move |ctx| ctx.dispatch(x, y, 1));
    }

    /// Group counts read from `args` at `offset` (declared `IndirectRead`).
    pub fn dispatch_indirect(mut self, args: BufferId, offset: u64) {
        let range = BufferRange::new(offset, 12);
        self.common.pass = self
            .common
            .pass
            .buffer_range(args, range, Access::IndirectRead);
        let program = self.program();
        self.common
            .finish(program, move |ctx| ctx.dispatch_indirect(args, offset));
    }
}

/// A draw pass being declared; `draw` adds it to the graph.
pub struct DrawPass<'g> {
    common: Common<'g>,
    desc: GraphicsDesc,
}

impl<'g> DrawPass<'g> {
    /// Specialization constants `(constant_id, value)` of every stage.
    pub fn spec(mut self, constants: &[(u32, u32)]) -> Self {
        self.desc.specialization = constants.to_vec();
        self
    }

    /// Push constants (at most `PUSH_CONSTANT_BYTES`).
    pub fn push(mut self, value: &impl bytemuck::NoUninit) -> Self {
        self.common.push = bytemuck::bytes_of(value).to_vec();
        self
    }

    /// A color attachment at mip 0; attachment order is the MRT location order.
    pub fn color(mut self, image: ImageId, load: Load) -> Self {
        self.common.pass = self.common.pass.color(image, load);
        self
    }

    /// The depth attachment.
    pub fn depth(mut self, image: ImageId, load: Load) -> Self {
        self.common.pass = self.common.pass.depth(image, load);
        self
    }

    /// Accesses beyond the bind list and attachments (indirect arguments, index buffers).
    pub fn declare(mut self, f: impl FnOnce(PassBuilder<'g>) -> PassBuilder<'g>) -> Self {
        self.common.pass = f(self.common.pass);
        self
    }

    /// Adds the pass: bind, push, then `draw` records the draw command.
    pub fn draw(self, draw: impl Fn(&PassContext<'_>) + 'static) {
        let stages = stages_of(&self.desc.shaders);
        let program = Program {
            layout: bind::layout(&self.common.binds, stages),
            kind: ProgramKind::Graphics(self.desc),
        };
        self.common.finish(program, draw);
    }
}

impl GraphBuilder {
    /// Starts a compute pass running `shader` over `binds`.
    pub fn compute(&mut self, name: &str, shader: &str, binds: &[Bind]) -> ComputePass<'_> {
        ComputePass {
            common: Common::new(self, name, binds),
            shader: shader.into(),
            spec: Vec::new(),
        }
    }

    /// Starts a draw pass with the pipeline state `desc` over `binds`, every binding visible to
    /// every stage of its shaders.
    pub fn draw(&mut self, name: &str, desc: GraphicsDesc, binds: &[Bind]) -> DrawPass<'_> {
        DrawPass {
            common: Common::new(self, name, binds),
            desc,
        }
    }
}

impl PassContext<'_> {
    /// The pipeline the graph created for this pass (`GraphBuilder::compute` / `draw`).
    fn pipeline(&self) -> &Pipeline {
        self.pipeline
            .unwrap_or_else(|| panic!("pass '{}' was declared without a program", self.pass_name()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::graph::Stages;
    use ash::vk;

    #[test]
    fn with_replaces_by_binding_number_and_appends_new_ones() {
        let (a, b, c) = (BufferId(0), BufferId(1), BufferId(2));
        let binds = Binds::from([Bind::reads(0, a), Bind::writes(3, b)]);
        let swapped = binds.with(Bind::updates(3, c));
        assert_eq!(swapped[..], [Bind::reads(0, a), Bind::updates(3, c)]);
        let grown = binds.with(Bind::uniform(5, c, Stages::Compute));
        assert_eq!(grown.len(), 3);
        assert_eq!(grown[2].binding, 5);
        assert_eq!(binds.len(), 2, "the original list is unchanged");
    }

    #[test]
    fn a_compute_pass_declares_its_binds_and_its_indirect_arguments() {
        let mut g = GraphBuilder::new();
        let (input, args) = (
            g.buffer("in", 64, vk::BufferUsageFlags::empty()),
            g.buffer("args", 64, vk::BufferUsageFlags::empty()),
        );
        g.compute("c", "x.comp", &[Bind::reads(1, input)])
            .spec(&[(0, 4)])
            .dispatch_indirect(args, 16);
        let pass = &g.passes[0];
        assert_eq!(pass.uses.len(), 2);
        let program = pass.program.as_ref().expect("a program");
        assert_eq!(
            program.kind,
            ProgramKind::Compute {
                shader: "x.comp".into(),
                spec: vec![(0, 4)],
            }
        );
        assert_eq!(
            program.layout,
            bind::compute_layout(&[Bind::reads(1, input)])
        );
    }
}
