//! Where a streamed file's bytes come from: a local file (positioned reads, no shared cursor,
//! so decoding threads read in parallel) or an HTTP(S) server answering range requests.
//!
//! Every read is one `(offset, length)` range checked against the source's length first. An
//! HTTP read that fails with a server error (5xx), a timeout or a dropped connection is
//! retried with exponential backoff; a client error (404, 403, …) or a server that ignores
//! ranges is reported at once. Errors name the source and the byte range. The HTTP files of
//! one scene share an [`HttpPool`]: one agent, whose connections are kept alive and reused
//! across requests and files, and a cap on the requests in flight.

use std::fs::File;
use std::os::unix::fs::FileExt;
use std::path::Path;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Condvar, Mutex};
use std::time::Duration;

/// A read that failed: the message names the source and the range.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SourceError {
    pub message: String,
}

impl std::fmt::Display for SourceError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.message)
    }
}

impl std::error::Error for SourceError {}

/// Random access to the bytes of one file.
pub trait ByteSource: Send + Sync {
    /// The path or URL, for messages.
    fn name(&self) -> &str;
    /// Length in bytes.
    fn len(&self) -> u64;
    /// The `len` bytes at `at`.
    fn read_at(&self, at: u64, len: u64) -> Result<Vec<u8>, SourceError>;
    /// Bytes read so far (for the viewer's HUD and reports).
    fn bytes_read(&self) -> u64;
    /// Reads (requests to a server) so far.
    fn reads(&self) -> u64;

    fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// Opens `location`: an `http://` or `https://` URL, or a local path.
pub fn open(location: &str, http: &HttpOptions) -> Result<Arc<dyn ByteSource>, SourceError> {
    open_in(location, &HttpPool::new(http))
}

/// [`open`], a URL read through `pool`'s connections.
pub fn open_in(location: &str, pool: &Arc<HttpPool>) -> Result<Arc<dyn ByteSource>, SourceError> {
    if is_url(location) {
        Ok(Arc::new(HttpSource::open(location, pool)?))
    } else {
        Ok(Arc::new(FileSource::open(Path::new(location))?))
    }
}

/// Whether `location` names a URL rather than a file.
pub fn is_url(location: &str) -> bool {
    let lower = location.to_ascii_lowercase();
    lower.starts_with("http://") || lower.starts_with("https://")
}

fn range_check(name: &str, at: u64, len: u64, size: u64) -> Result<(), SourceError> {
    if at.checked_add(len).is_none_or(|end| end > size) {
        return Err(SourceError {
            message: format!(
                "{name}: bytes {at}..{} lie past the end of the file at byte {size}",
                at.saturating_add(len)
            ),
        });
    }
    Ok(())
}

/// A local file read with `pread`.
pub struct FileSource {
    name: String,
    file: File,
    len: u64,
    read: AtomicU64,
    reads: AtomicU64,
}

impl FileSource {
    pub fn open(path: &Path) -> Result<Self, SourceError> {
        let name = path.display().to_string();
        let fail = |e: std::io::Error| SourceError {
            message: format!("{name}: {e}"),
        };
        let file = File::open(path).map_err(fail)?;
        let meta = file.metadata().map_err(fail)?;
        if !meta.is_file() {
            return Err(SourceError {
                message: format!("{name}: not a regular file"),
            });
        }
        Ok(Self {
            len: meta.len(),
            name,
            file,
            read: AtomicU64::new(0),
            reads: AtomicU64::new(0),
        })
    }
}

impl ByteSource for FileSource {
    fn name(&self) -> &str {
        &self.name
    }

    fn len(&self) -> u64 {
        self.len
    }

    fn read_at(&self, at: u64, len: u64) -> Result<Vec<u8>, SourceError> {
        range_check(&self.name, at, len, self.len)?;
        let mut bytes = vec![0; len as usize];
        self.file
            .read_exact_at(&mut bytes, at)
            .map_err(|e| SourceError {
                message: format!("{}: bytes {at}..{}: {e}", self.name, at + len),
            })?;
        self.read.fetch_add(len, Ordering::Relaxed);
        self.reads.fetch_add(1, Ordering::Relaxed);
        Ok(bytes)
    }

    fn bytes_read(&self) -> u64 {
        self.read.load(Ordering::Relaxed)
    }

    fn reads(&self) -> u64 {
        self.reads.load(Ordering::Relaxed)
    }
}

/// Retry and timeout settings of HTTP reads.
#[derive(Clone, Debug)]
pub struct HttpOptions {
    /// Attempts per range (the first included).
    pub attempts: u32,
    /// Wait before the first retry; doubled for each next one.
    pub backoff: Duration,
    /// Limit on one request, connection included.
    pub timeout: Duration,
    /// Requests in flight at most, over every file read through one [`HttpPool`].
    pub connections: usize,
}

impl Default for HttpOptions {
    fn default() -> Self {
        Self {
            attempts: 5,
            backoff: Duration::from_millis(200),
            timeout: Duration::from_secs(20),
            connections: DEFAULT_CONNECTIONS,
        }
    }
}

/// Default of [`HttpOptions::connections`].
pub const DEFAULT_CONNECTIONS: usize = 8;

/// What the HTTP files of one dataset share: one agent (its connections kept alive and reused
/// from request to request and file to file) and a cap on the requests in flight.
pub struct HttpPool {
    agent: ureq::Agent,
    options: HttpOptions,
    /// Requests in flight.
    busy: Mutex<usize>,
    freed: Condvar,
}

impl HttpPool {
    pub fn new(options: &HttpOptions) -> Arc<Self> {
        let connections = options.connections.max(1);
        let agent: ureq::Agent = ureq::Agent::config_builder()
            .timeout_global(Some(options.timeout))
            .http_status_as_error(false)
            .max_idle_connections(connections)
            .max_idle_connections_per_host(connections)
            .build()
            .into();
        Arc::new(Self {
            agent,
            options: options.clone(),
            busy: Mutex::new(0),
            freed: Condvar::new(),
        })
    }

    /// Runs `f` once fewer than `connections` requests are in flight.
    fn limited<T>(&self, f: impl FnOnce() -> T) -> T {
        {
            let mut busy = self.busy.lock().unwrap_or_else(|e| e.into_inner());
            while *busy >= self.options.connections.max(1) {
                busy = self.freed.wait(busy).unwrap_or_else(|e| e.into_inner());
            }
            *busy += 1;
        }
        let out = f();
        *self.busy.lock().unwrap_or_else(|e| e.into_inner()) -= 1;
        self.freed.notify_one();
        out
    }
}

/// A file on an HTTP(S) server, read with `Range` requests.
pub struct HttpSource {
    url: String,
    pool: Arc<HttpPool>,
    len: u64,
    read: AtomicU64,
    reads: AtomicU64,
}

/// Why one attempt failed, and whether another may succeed.
struct Attempt {
    message: String,
    retry: bool,
}

impl HttpSource {
    /// Asks for the first byte to learn the length (from `Content-Range`) and to check that
    /// the server honours ranges.
    pub fn open(url: &str, pool: &Arc<HttpPool>) -> Result<Self, SourceError> {
        let mut source = Self {
            url: url.to_owned(),
            pool: pool.clone(),
            len: 0,
            read: AtomicU64::new(0),
            reads: AtomicU64::new(0),
        };
        let (_, total) = source.fetch(0, 1)?;
        source.len = total;
        Ok(source)
    }

    /// The bytes `at..at + len` and the file's length, with retries.
    fn fetch(&self, at: u64, len: u64) -> Result<(Vec<u8>, u64), SourceError> {
        let mut wait = self.pool.options.backoff;
        let mut attempt = 1;
        loop {
            self.reads.fetch_add(1, Ordering::Relaxed);
            match self.pool.limited(|| self.attempt(at, len)) {
                Ok(done) => {
                    self.read.fetch_add(len, Ordering::Relaxed);
                    return Ok(done);
                }
                Err(e) if e.retry && attempt < self.pool.options.attempts => {
                    std::thread::sleep(wait);
                    wait *= 2;
                    attempt += 1;
                }
                Err(e) => {
                    let tries = if attempt > 1 {
                        format!(" (after {attempt} attempts)")
                    } else {
                        String::new()
                    };
                    return Err(SourceError {
                        message: format!(
                            "{}: bytes {at}..{}: {}{tries}",
                            self.url,
                            at + len,
                            e.message
                        ),
                    });
                }
            }
        }
    }

    fn attempt(&self, at: u64, len: u64) -> Result<(Vec<u8>, u64), Attempt> {
        let end = at + len - 1;
        let response = self
            .pool
            .agent
            .get(&self.url)
            .header("Range", &format!("bytes={at}-{end}"))
            .call()
            .map_err(|e| Attempt {
                message: e.to_string(),
                retry: !matches!(e, ureq::Error::BadUri(_) | ureq::Error::Protocol(_)),
            })?;
        let status = response.status().as_u16();
        match status {
            206 => {}
            200 => {
                return Err(Attempt {
                    message: "the server ignores range requests (200 instead of 206 Partial Content); a streamed file needs a server that honours them".into(),
                    retry: false,
                })
            }
            416 => {
                return Err(Attempt {
                    message: "range not satisfiable (416): the file is shorter than its header says".into(),
                    retry: false,
                })
            }
            s => {
                return Err(Attempt {
                    message: format!("HTTP {s}"),
                    retry: s >= 500 || s == 408 || s == 429,
                })
            }
        }
        let total = response
            .headers()
            .get("content-range")
            .and_then(|v| v.to_str().ok())
            .and_then(|v| v.rsplit_once('/'))
            .and_then(|(_, t)| t.trim().parse::<u64>().ok())
            .ok_or_else(|| Attempt {
                message: "a 206 response without a Content-Range total".into(),
                retry: false,
            })?;
        let mut body = Vec::with_capacity(len as usize);
        std::io::Read::read_to_end(
            &mut std::io::Read::take(response.into_body().into_reader(), len + 1),
            &mut body,
        )
        .map_err(|e| Attempt {
            message: format!("reading the body: {e}"),
            retry: true,
        })?;
        if body.len() as u64 != len {
            return Err(Attempt {
                message: format!("{} bytes received, {len} asked for", body.len()),
                retry: true,
            });
        }
        Ok((body, total))
    }
}

impl ByteSource for HttpSource {
    fn name(&self) -> &str {
        &self.url
    }

    fn len(&self) -> u64 {
        self.len
    }

    fn read_at(&self, at: u64, len: u64) -> Result<Vec<u8>, SourceError> {
        range_check(&self.url, at, len, self.len)?;
        if len == 0 {
            return Ok(Vec::new());
        }
        self.fetch(at, len).map(|(bytes, _)| bytes)
    }

    fn bytes_read(&self) -> u64 {
        self.read.load(Ordering::Relaxed)
    }

    fn reads(&self) -> u64 {
        self.reads.load(Ordering::Relaxed)
    }
}
