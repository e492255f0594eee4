//! Uploading a scene: one [`upload`] builds the point streams, the face and line indices and
//! whatever the chosen methods read beyond them (the object texture of level of detail, the
//! normal fields of Phong splatting, hidden point removal's radius data);
//! [`GpuScene::complete`] adds what a method chosen later reads.

pub mod streamed;

use std::sync::{Arc, Mutex};

use anyhow::{bail, Context as _, Result};
use ash::vk;
use glam::Vec3;

use crate::color::Coloring;
use crate::gpu::{Buffer, Context};
use crate::lod::{self, Hierarchy, ObjectTexture};
use crate::point_streams::upload::{default_segment_points, DEFAULT_CHUNK_BYTES};
use crate::point_streams::{upload as upload_streams, GpuStreams, StreamLayout};
use crate::scene::{normal_field, Cloud, Up};

/// What to upload beyond the point streams, and how to cut them.
#[derive(Clone, Copy, Debug)]
pub struct UploadOptions {
    /// Points per segment; `None` fits segments to the device's `maxStorageBufferRange`.
    pub segment_points: Option<u64>,
    /// Bytes per staging chunk.
    pub chunk_bytes: u64,
    /// What the points are colored by (`color::select`); only its scalar field reaches the
    /// GPU. `None`: the cloud's colors when it has them, else the lit base color.
    pub coloring: Option<Coloring>,
    /// The object texture of level of detail (`crate::lod`, for the methods with `needs_lod`;
    /// the cloud needs normals and radii).
    pub lod: bool,
    /// The linear normal fields of Phong splatting (`crate::scene::normal_field`, for the
    /// methods with `needs_normal_field`).
    pub normal_field: bool,
    /// Hidden point removal's flipping-radius data (`HprScene`, for the methods with
    /// `needs_hpr`).
    pub hpr: bool,
}

impl Default for UploadOptions {
    fn default() -> Self {
        Self {
            segment_points: None,
            chunk_bytes: DEFAULT_CHUNK_BYTES,
            coloring: None,
            lod: false,
            normal_field: false,
            hpr: false,
        }
    }
}

impl UploadOptions {
    /// The default options colored by `coloring`.
    pub fn colored(coloring: Coloring) -> Self {
        Self {
            coloring: Some(coloring),
            ..Self::default()
        }
    }
}

/// Scene facts the frame loop needs after upload.
#[derive(Clone, Copy, Debug)]
pub struct SceneInfo {
    pub centre: Vec3,
    pub radius: f32,
    pub points: u32,
    pub has_colors: bool,
    pub has_normals: bool,
    /// The cloud's up axis.
    pub up: Up,
    /// The local frame's origin in the file's coordinates (`Cloud::origin`).
    pub origin: glam::DVec3,
    /// What the points are colored by (`color::select`); its scalar field is the one uploaded.
    pub coloring: Coloring,
}

/// What hidden point removal reads beyond the streams.
pub struct HprScene {
    /// R / D² of the flipping radius from the sampling density (`hpr::Radius::Density`:
    /// κ / the sample spacing).
    pub density: f32,
    /// The bounding box's diagonal: the `radius` factor multiplies it.
    pub diagonal: f32,
    /// The bounding sphere of the points on the GPU (`methods::hpr::bounding_sphere`),
    /// computed by the first HPR graph built on the scene and kept for the later ones.
    pub sphere: Mutex<Option<Arc<Buffer>>>,
}

impl HprScene {
    fn new(cloud: &Cloud) -> Self {
        Self {
            density: (crate::hpr::DENSITY_KAPPA / crate::hpr::spacing(cloud)) as f32,
            diagonal: crate::hpr::diagonal(&cloud.positions) as f32,
            sphere: Mutex::new(None),
        }
    }
}

/// The scene on the GPU.
pub struct GpuScene {
    pub streams: GpuStreams,
    pub indices: Option<Arc<Buffer>>,
    /// One bit per point in stream order (32 to a word): set for the vertices a face or a
    /// line references (hybrid scenes draw those as triangles or lines, the rest as points).
    pub face_vertices: Option<Arc<Buffer>>,
    /// Ribbon and tube segments (index pairs in stream order) and their index counts.
    pub ribbons: Option<(Arc<Buffer>, u32)>,
    pub tubes: Option<(Arc<Buffer>, u32)>,
    pub point_count: u32,
    pub index_count: u32,
    /// The object texture of level of detail (000 ch. 7), when uploaded
    /// (`UploadOptions::lod`).
    pub lod: Option<Arc<GpuLod>>,
    /// Hidden point removal's data, when uploaded (`UploadOptions::hpr`).
    pub hpr: Option<HprScene>,
    /// A streamed cloud's pool (`streamed::StreamedScene`): which batches hold points changes
    /// per frame, so renderers read a per-frame batch table (`Renderer::set_batches`).
    pub streamed: bool,
    /// Stream indices a draw of every point covers: `point_count`, or for a streamed pool the
    /// end of its highest occupied slot (set per frame).
    pub draw_points: DrawCount,
}

/// A point count read when a frame is recorded (a streamed pool's changes per frame).
#[derive(Clone, Debug, Default)]
pub struct DrawCount(Arc<std::sync::atomic::AtomicU32>);

impl DrawCount {
    pub fn new(n: u32) -> Self {
        Self(Arc::new(std::sync::atomic::AtomicU32::new(n)))
    }

    pub fn get(&self) -> u32 {
        self.0.load(std::sync::atomic::Ordering::Relaxed)
    }

    pub fn set(&self, n: u32) {
        self.0.store(n, std::sync::atomic::Ordering::Relaxed);
    }
}

impl GpuScene {
    /// Adds what `options` asks for and the scene was uploaded without (the object texture,
    /// the normal fields' stream, HPR's data) from `cloud`, the cloud it was uploaded from.
    pub fn complete(
        &mut self,
        ctx: &Arc<Context>,
        cloud: &Cloud,
        options: &UploadOptions,
    ) -> Result<()> {
        if options.lod && self.lod.is_none() {
            self.lod = Some(Arc::new(upload_lod(ctx, cloud)?));
        }
        if options.normal_field && !self.streams.normal_field {
            let field = normal_field::fit_cloud(cloud);
            self.streams
                .add_normal_field(ctx, cloud, field, options.chunk_bytes)?;
        }
        if options.hpr && self.hpr.is_none() {
            self.hpr = Some(HprScene::new(cloud));
        }
        Ok(())
    }
}

/// Uploads `cloud` as point streams (Morton-ordered batches, segments fitted to the device),
/// its triangle indices and line segments (remapped to stream order) and what `options` asks
/// for beyond them.
pub fn upload(
    ctx: &Arc<Context>,
    cloud: &Cloud,
    options: &UploadOptions,
) -> Result<(GpuScene, SceneInfo)> {
    // The passes assume finite positions (a NaN projects to pixel 0): a cloud built without a
    // loader, which drops them, is uploaded without them.
    let finite;
    let cloud = if cloud.positions.iter().all(|p| p.is_finite()) {
        cloud
    } else {
        let mut copy = cloud.clone();
        copy.retain_finite();
        finite = copy;
        &finite
    };
    let coloring = options
        .coloring
        .unwrap_or_else(|| Coloring::default_for(cloud.colors.is_some()));
    let (centre, radius) = cloud.bounding_sphere().unwrap_or((Vec3::ZERO, 1.0));
    let segment_points = options
        .segment_points
        .unwrap_or_else(|| default_segment_points(ctx));
    let mut layout =
        StreamLayout::new(cloud, segment_points, coloring.scalar).map_err(anyhow::Error::msg)?;
    if options.normal_field {
        layout = layout.with_normal_field(normal_field::fit_cloud(cloud));
    }
    let streams = upload_streams::upload(ctx, cloud, &layout, options.chunk_bytes)?;
    let inverse = layout.inverse();
    let remap = |i: u32| inverse.get(i as usize).copied().unwrap_or(0);
    // Vertices of faces and lines are drawn as those primitives by hybrid methods.
    let mut mask = vec![0u32; cloud.len().div_ceil(32).max(1)];
    let mut primitive_buffer = |name: &str, indices: Vec<u32>, usage| -> Result<_> {
        for &i in &indices {
            mask[(i / 32) as usize] |= 1 << (i % 32);
        }
        let count = u32::try_from(indices.len()).context("more than 4G indices")?;
        let buffer = Buffer::with_data(ctx, name, bytemuck::cast_slice(&indices), usage)?;
        Ok((Arc::new(buffer), count))
    };
    let index_usage = vk::BufferUsageFlags::INDEX_BUFFER | vk::BufferUsageFlags::STORAGE_BUFFER;
    let faces = match &cloud.faces {
        Some(f) if !f.is_empty() => {
            let indices = f.iter().flatten().map(|&i| remap(i)).collect();
            Some(primitive_buffer("indices", indices, index_usage)?)
        }
        _ => None,
    };
    let mut segments = |name: &str, pairs: &[[u32; 2]]| -> Result<_> {
        if pairs.is_empty() {
            return Ok(None);
        }
        let indices = pairs.iter().flatten().map(|&i| remap(i)).collect();
        primitive_buffer(name, indices, vk::BufferUsageFlags::INDEX_BUFFER).map(Some)
    };
    let (ribbons, tubes) = match &cloud.lines {
        Some(l) => (
            segments("ribbons", &l.ribbons)?,
            segments("tubes", &l.tubes)?,
        ),
        None => (None, None),
    };
    let face_vertices = if faces.is_some() || ribbons.is_some() || tubes.is_some() {
        Some(Arc::new(Buffer::with_data(
            ctx,
            "face-vertices",
            bytemuck::cast_slice(&mask),
            vk::BufferUsageFlags::STORAGE_BUFFER,
        )?))
    } else {
        None
    };
    let (indices, index_count) = faces.map_or((None, 0), |(b, n)| (Some(b), n));
    let point_count = streams.point_count;
    let lod = if options.lod {
        Some(Arc::new(upload_lod(ctx, cloud)?))
    } else {
        None
    };
    Ok((
        GpuScene {
            streams,
            indices,
            face_vertices,
            ribbons,
            tubes,
            point_count,
            index_count,
            lod,
            hpr: options.hpr.then(|| HprScene::new(cloud)),
            streamed: false,
            draw_points: DrawCount::new(point_count),
        },
        SceneInfo {
            centre,
            radius,
            points: point_count,
            has_colors: cloud.colors.is_some(),
            has_normals: cloud.normals.is_some(),
            up: cloud.up,
            origin: cloud.origin,
            coloring,
        },
    ))
}

/// An object texture uploaded: its patches (`GpuLodPatch`) and vertices (`GpuLodVertex`).
pub struct GpuLod {
    pub patches: Arc<Buffer>,
    pub vertices: Arc<Buffer>,
    pub patch_count: u32,
    /// The object texture's levels (`ObjectTexture::levels`): the counters' per-level words
    /// a path writes.
    pub levels: u32,
    /// The longest list a view selects (`ObjectTexture::max_selected`).
    pub max_selected: u32,
}

impl GpuLod {
    pub fn upload(ctx: &Arc<Context>, texture: &ObjectTexture) -> Result<GpuLod> {
        let usage = vk::BufferUsageFlags::STORAGE_BUFFER;
        let patches = texture.gpu_patches();
        let vertices = texture.gpu_vertices();
        Ok(GpuLod {
            patches: Arc::new(Buffer::with_data(
                ctx,
                "lod.patches",
                bytemuck::cast_slice(&patches),
                usage,
            )?),
            vertices: Arc::new(Buffer::with_data(
                ctx,
                "lod.vertices",
                bytemuck::cast_slice(&vertices),
                usage,
            )?),
            patch_count: patches.len() as u32,
            levels: texture.levels,
            max_selected: texture.max_selected(),
        })
    }
}

/// Builds the object texture of `cloud` (`lod::DEFAULT_LEVELS` levels) and uploads it.
pub fn upload_lod(ctx: &Arc<Context>, cloud: &Cloud) -> Result<GpuLod> {
    let (Some(normals), Some(radii)) = (&cloud.normals, &cloud.radii) else {
        bail!("level of detail needs a cloud with normals and radii");
    };
    let hierarchy = Hierarchy::build(&cloud.positions, normals, radii, lod::DEFAULT_LEVELS);
    GpuLod::upload(
        ctx,
        &ObjectTexture::new(&hierarchy, cloud.colors.as_deref()),
    )
}
