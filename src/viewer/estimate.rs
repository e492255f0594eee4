//! Normals and radii estimated on a worker thread while the viewer draws the raw points: the
//! viewer polls it every frame, shows its progress in the HUD and, once it is done, uploads
//! the completed cloud, which turns on lit shading. A scripted tour waits for it before its
//! first step, so that its screenshots do not depend on the worker's speed.

use std::path::PathBuf;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::mpsc::{self, Receiver, TryRecvError};
use std::sync::Arc;
use std::time::Instant;

use anyhow::{anyhow, Result};
use glam::Vec3;

use crate::scene::preprocess::{self, PreprocessOptions};
use crate::scene::Cloud;

/// What the worker estimates with.
#[derive(Clone, Debug)]
pub struct EstimateOptions {
    /// Neighbours for k-NN normals and radii (at least 1).
    pub k: usize,
    /// The input file whose `FILE.surfel-cache` receives the result (`--cache`).
    pub cache: Option<PathBuf>,
}

/// A finished estimate.
pub struct Estimated {
    pub normals: Vec<Vec3>,
    pub radii: Vec<f32>,
    pub seconds: f64,
    /// Why the cache could not be written, when it could not.
    pub cache_error: Option<String>,
}

/// The running worker.
pub struct Estimation {
    receiver: Receiver<Estimated>,
    done: Arc<AtomicUsize>,
    total: usize,
    pub k: usize,
}

impl Estimation {
    /// Starts estimating what `cloud` lacks on a copy of its positions.
    pub fn start(cloud: &Cloud, options: &EstimateOptions) -> Self {
        let mut work = Cloud {
            positions: cloud.positions.clone(),
            normals: cloud.normals.clone(),
            radii: cloud.radii.clone(),
            sensors: cloud.sensors.clone(),
            up: cloud.up,
            survey: cloud.survey,
            ..Cloud::default()
        };
        let (sender, receiver) = mpsc::channel();
        let done = Arc::new(AtomicUsize::new(0));
        let counter = Arc::clone(&done);
        let options = options.clone();
        let settings = PreprocessOptions {
            k: options.k.max(1),
            progress: false,
            ..PreprocessOptions::default()
        };
        std::thread::spawn(move || {
            let start = Instant::now();
            preprocess::preprocess_with(&mut work, &settings, &|n| {
                counter.fetch_add(n, Ordering::Relaxed);
            });
            let seconds = start.elapsed().as_secs_f64();
            let normals = work.normals.unwrap_or_default();
            let radii = work.radii.unwrap_or_default();
            let cache_error = options.cache.and_then(|input| {
                preprocess::save_cache(&input, &settings, &normals, &radii)
                    .err()
                    .map(|e| {
                        format!(
                            "{}: cannot write the cache: {e}",
                            preprocess::cache_path(&input).display()
                        )
                    })
            });
            // A viewer closed meanwhile has nobody left to tell.
            let _ = sender.send(Estimated {
                normals,
                radii,
                seconds,
                cache_error,
            });
        });
        Estimation {
            receiver,
            done,
            total: cloud.len(),
            k: settings.k,
        }
    }

    /// The finished estimate, waiting for it when `wait`; `None` while it runs.
    pub fn poll(&self, wait: bool) -> Result<Option<Estimated>> {
        let stopped = || anyhow!("the estimation of normals and radii stopped");
        if wait {
            return self.receiver.recv().map(Some).map_err(|_| stopped());
        }
        match self.receiver.try_recv() {
            Ok(done) => Ok(Some(done)),
            Err(TryRecvError::Empty) => Ok(None),
            Err(TryRecvError::Disconnected) => Err(stopped()),
        }
    }

    /// Percent of the points done.
    pub fn percent(&self) -> usize {
        (self.done.load(Ordering::Relaxed) * 100 / self.total.max(1)).min(100)
    }
}
