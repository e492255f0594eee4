//! The GPU radix sort and segmented maximum (`methods::common::sort`) on lavapipe under
//! synchronization validation, element for element against the CPU: a stable sort by the low
//! key bits (values hold the original index, keys repeat often), including more block sums
//! than the scan workgroup handles at once, and the per-key maximum of sorted data with
//! segments crossing tiles.

use crate::common;

use std::sync::Arc;

use ash::vk;
use surfel::gpu::{Buffer, Context};
use surfel::graph::{Access, BufferId, GraphBuilder};
use surfel::methods::common::sort::{add_segmented_max, add_sort, RadixSort};

/// A small deterministic generator (64-bit LCG, high bits out).
struct Lcg(u64);

impl Lcg {
    fn next(&mut self) -> u32 {
        self.0 = self
            .0
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (self.0 >> 32) as u32
    }

    fn below(&mut self, n: u32) -> u32 {
        self.next() % n
    }

    fn wide(&mut self) -> u64 {
        u64::from(self.next()) << 32 | u64::from(self.next())
    }
}

fn bytes<T: bytemuck::Pod>(data: &[T]) -> Vec<u8> {
    bytemuck::cast_slice(data).to_vec()
}

/// A device-local storage buffer holding `data`, imported after its upload.
fn input(ctx: &Arc<Context>, g: &mut GraphBuilder, name: &str, data: &[u8]) -> BufferId {
    let usage = vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::TRANSFER_SRC;
    let buffer = Buffer::with_data(ctx, name, data, usage).expect("upload");
    g.import_buffer_with(name, Arc::new(buffer), Access::TransferDst)
}

/// Copies the first `size` bytes of `src` into a new host-visible buffer after the passes
/// declared so far.
fn read_back(ctx: &Arc<Context>, g: &mut GraphBuilder, src: BufferId, size: u64) -> Arc<Buffer> {
    let host = Arc::new(Buffer::readback(ctx, "readback", size).expect("readback"));
    let id = g.import_buffer("readback", host.clone());
    let region = [vk::BufferCopy {
        src_offset: 0,
        dst_offset: 0,
        size,
    }];
    g.copy_buffer("download", src, id, &region);
    g.pass("host").buffer(id, Access::HostRead).record(|_| {});
    host
}

fn read_u32(buffer: &Buffer) -> Vec<u32> {
    let bytes = buffer.mapped().expect("mapped");
    bytes
        .chunks_exact(4)
        .map(|w| u32::from_ne_bytes(w.try_into().expect("4 bytes")))
        .collect()
}

fn read_u64(buffer: &Buffer) -> Vec<u64> {
    let bytes = buffer.mapped().expect("mapped");
    bytes
        .chunks_exact(8)
        .map(|w| u64::from_ne_bytes(w.try_into().expect("8 bytes")))
        .collect()
}

/// `count` keys, about half drawn from 40 random 32-bit keys (many duplicates, differing in
/// high bits too) and half uniform; values are random high words over the original index.
fn pairs(rng: &mut Lcg, count: usize) -> (Vec<u32>, Vec<u64>) {
    let pool: Vec<u32> = (0..40).map(|_| rng.next()).collect();
    let keys = (0..count)
        .map(|_| {
            if rng.below(2) == 0 {
                pool[rng.below(40) as usize]
            } else {
                rng.next()
            }
        })
        .collect();
    let values = (0..count as u64)
        .map(|i| u64::from(rng.next()) << 32 | i)
        .collect();
    (keys, values)
}

/// Sorts `count` random pairs by each of `key_bits` on the GPU and compares with a stable CPU
/// sort by the same bits.
fn check_sort(ctx: &Arc<Context>, p: &RadixSort, rng: &mut Lcg, count: usize, key_bits: &[u32]) {
    for &key_bits in key_bits {
        let (keys, values) = pairs(rng, count);
        let mut g = GraphBuilder::new();
        let key_in = input(ctx, &mut g, "keys", &bytes(&keys));
        let value_in = input(ctx, &mut g, "values", &bytes(&values));
        let (sorted_keys, sorted_values) =
            add_sort(&mut g, p, key_in, value_in, count as u32, key_bits);
        if count < 2 {
            assert_eq!((sorted_keys, sorted_values), (key_in, value_in));
        }
        if count == 0 {
            continue;
        }
        let key_host = read_back(ctx, &mut g, sorted_keys, count as u64 * 4);
        let value_host = read_back(ctx, &mut g, sorted_values, count as u64 * 8);
        g.compile(ctx).expect("compile").run_once(ctx).expect("run");
        let mask = if key_bits == 32 {
            u32::MAX
        } else {
            (1 << key_bits) - 1
        };
        let mut expected: Vec<(u32, u64)> = keys.into_iter().zip(values).collect();
        expected.sort_by_key(|&(k, _)| k & mask);
        let got_keys = read_u32(&key_host);
        let got_values = read_u64(&value_host);
        for (i, (k, v)) in expected.iter().enumerate() {
            assert_eq!(
                (got_keys[i], got_values[i]),
                (*k, *v),
                "count {count}, {key_bits} key bits: element {i} (original index {} expected)",
                v & 0xffff_ffff
            );
        }
    }
}

#[test]
fn radix_sort_matches_a_stable_cpu_sort() {
    let ctx = common::context();
    let p = RadixSort::new(&ctx).expect("radix sort");
    let mut rng = Lcg(7);
    for count in [0, 1, 1000, 100_003] {
        check_sort(&ctx, &p, &mut rng, count, &[5, 16, 24, 32]);
    }
    common::assert_clean(&ctx);
}

#[test]
fn radix_sort_scans_block_sums_in_more_than_one_chunk() {
    use surfel::layout::{SCAN_GROUP, SCAN_ITEMS, SORT_GROUP, SORT_ITEMS, SORT_RADIX};
    let ctx = common::context();
    let p = RadixSort::new(&ctx).expect("radix sort");
    // Just over one chunk of block sums: the single scan workgroup carries a running total.
    let chunk = (SCAN_GROUP * SCAN_ITEMS) as usize;
    let tiles = chunk * chunk / SORT_RADIX as usize + 3;
    let count = tiles * (SORT_GROUP * SORT_ITEMS) as usize - 5;
    check_sort(&ctx, &p, &mut Lcg(3), count, &[8]);
    common::assert_clean(&ctx);
}

#[test]
fn segmented_max_matches_the_cpu_per_key_maximum() {
    let ctx = common::context();
    RadixSort::new(&ctx).expect("64-bit atomics");
    let mut rng = Lcg(11);
    // Sorted keys with gaps: a segment filling exactly the first 256-element tile, then
    // segments of one element, a few elements, or hundreds to thousands (crossing tiles).
    let mut keys = vec![0u32; 256];
    let mut key = 0;
    while keys.len() < 60_000 {
        key += 1 + rng.below(3);
        let len = match rng.below(4) {
            0 => 1,
            1 => 1 + rng.below(8),
            2 => 200 + rng.below(3000),
            _ => 1 + rng.below(300),
        };
        keys.extend(std::iter::repeat_n(key, len as usize));
    }
    let keys = &keys[..keys.len() - 17];
    let count = keys.len();
    let values: Vec<u64> = (0..count).map(|_| rng.wide()).collect();
    let slots = key as usize + 2;
    // Keys present start at 0 (cleared by the caller); absent keys hold a marker that must
    // survive.
    let marker = 0xdead_beef_0bad_f00d_u64;
    let mut expected = vec![marker; slots];
    for &k in keys {
        expected[k as usize] = 0;
    }
    let initial = expected.clone();
    for (&k, &v) in keys.iter().zip(&values) {
        expected[k as usize] = expected[k as usize].max(v);
    }
    let mut g = GraphBuilder::new();
    let key_in = input(&ctx, &mut g, "keys", &bytes(keys));
    let value_in = input(&ctx, &mut g, "values", &bytes(&values));
    let out = input(&ctx, &mut g, "maxima", &bytes(&initial));
    add_segmented_max(&mut g, key_in, value_in, count as u32, out);
    let host = read_back(&ctx, &mut g, out, slots as u64 * 8);
    g.compile(&ctx)
        .expect("compile")
        .run_once(&ctx)
        .expect("run");
    let got = read_u64(&host);
    for (s, (value, want)) in got.iter().zip(&expected).enumerate() {
        assert_eq!(value, want, "key {s}");
    }
    common::assert_clean(&ctx);
}
