//! Fixed-size binary records (binary PLY vertices, LAS points) streamed from a file in blocks:
//! the next block is read while the current one is decoded in parallel, so a load holds the
//! decoded columns plus two blocks, never the whole file.

use std::io::Read;

use rayon::prelude::*;

use super::error::LoadError;
use super::progress::Progress;

/// Bytes decoded by one parallel task (a few records' worth of every output column stays in
/// cache while the task runs).
const TASK_BYTES: usize = 1 << 20;

/// Bytes read from a file per block.
pub(crate) const BLOCK_BYTES: usize = 16 << 20;

/// Files whose record data is at least this large show a progress bar (on a terminal).
pub(crate) const PROGRESS_MIN_BYTES: usize = 64 << 20;

/// Records per parallel task for records of `stride` bytes.
pub(crate) fn task_records(stride: usize) -> usize {
    (TASK_BYTES / stride.max(1)).max(1)
}

/// A vector of `n` copies of `value`, written in parallel (so the pages of a large column are
/// first touched by all threads, not one).
pub(crate) fn filled<T: Copy + Send + Sync>(value: T, n: usize) -> Vec<T> {
    let mut column = Vec::with_capacity(n);
    column.par_extend((0..n).into_par_iter().map(|_| value));
    column
}

/// Where a run of `count` records of `stride` bytes lies in a file.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Span {
    /// Byte offset of the first record (for error messages).
    pub at: usize,
    pub count: usize,
    pub stride: usize,
}

/// Reads the records of `span` from `read` (positioned at the first record) in blocks of about
/// `block_bytes` and calls `decode(first_record, block)` for each block in order, reading the
/// next block while `decode` runs. `progress` advances by the bytes decoded.
pub(crate) fn for_each_block<R: Read + Send>(
    file: &str,
    read: &mut R,
    span: Span,
    block_bytes: usize,
    progress: &Progress,
    mut decode: impl FnMut(usize, &[u8]) + Send,
) -> Result<(), LoadError> {
    let per_block = (block_bytes / span.stride.max(1)).max(1);
    let fill = |read: &mut R, buf: &mut Vec<u8>, first: usize| {
        let records = per_block.min(span.count - first);
        buf.resize(records * span.stride, 0);
        read.read_exact(buf).map_err(|e| {
            LoadError::at_byte(
                file,
                span.at + first * span.stride,
                format!(
                    "cannot read records {first}..{} of {}: {e}",
                    first + records,
                    span.count
                ),
            )
        })
    };
    let (mut current, mut next) = (Vec::new(), Vec::new());
    if span.count > 0 {
        fill(read, &mut current, 0)?;
    }
    let mut first = 0;
    while first < span.count {
        let after = first + per_block.min(span.count - first);
        let (filled, ()) = rayon::join(
            || {
                if after < span.count {
                    fill(read, &mut next, after)
                } else {
                    Ok(())
                }
            },
            || decode(first, &current),
        );
        filled?;
        progress.advance(current.len());
        std::mem::swap(&mut current, &mut next);
        first = after;
    }
    progress.finish();
    Ok(())
}
