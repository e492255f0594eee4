//! The last line of defence against third-party parsers: a panic inside the `las`, `laz`,
//! `e57` or `obj` crates on input the checks before them let through becomes an error message
//! instead of a crash. The checks stay the first line: every panic found so far has its own
//! check, and this only catches what is still unknown.

use std::panic::{self, AssertUnwindSafe};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Mutex, Once, OnceLock};

/// Guarded calls running now, on any thread.
static ACTIVE: AtomicUsize = AtomicUsize::new(0);
/// The message of the last panic inside a guarded call.
static MESSAGE: Mutex<Option<String>> = Mutex::new(None);
static HOOK: Once = Once::new();

/// Runs `f`, a call into a third-party parser; a panic in it (or in the threads it runs on) is
/// returned as its message, and not printed. Panics elsewhere while a guarded call runs are
/// reported as before.
pub(crate) fn third_party<T>(f: impl FnOnce() -> T) -> Result<T, String> {
    HOOK.call_once(|| {
        let previous = panic::take_hook();
        panic::set_hook(Box::new(move |info| {
            if ACTIVE.load(Ordering::SeqCst) == 0 {
                return previous(info);
            }
            let text = info
                .payload()
                .downcast_ref::<&str>()
                .map(|s| (*s).to_owned())
                .or_else(|| info.payload().downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "panic".to_owned());
            let at = info
                .location()
                .map(|l| {
                    format!(
                        " at {}:{}",
                        l.file().rsplit("/src/").next().unwrap_or(""),
                        l.line()
                    )
                })
                .unwrap_or_default();
            *MESSAGE.lock().unwrap_or_else(|e| e.into_inner()) = Some(format!("{text}{at}"));
        }));
    });
    ACTIVE.fetch_add(1, Ordering::SeqCst);
    let result = panic::catch_unwind(AssertUnwindSafe(f));
    ACTIVE.fetch_sub(1, Ordering::SeqCst);
    result.map_err(|_| {
        let message = MESSAGE.lock().unwrap_or_else(|e| e.into_inner()).take();
        format!(
            "the decoder failed on corrupt data ({})",
            message.unwrap_or_else(|| "no message".to_owned())
        )
    })
}

/// Stack of the threads that run the `laz` crate's decoders. Its GPS-time decoder (point
/// formats 1 and 3) calls itself once per sequence switch it decodes, and corrupt data can
/// switch tens of thousands of times on a few hundred bytes: an 849-byte file found by fuzzing
/// needed 150 MB of stack, and overflowing a stack aborts the process, which no check or
/// [`third_party`] can catch. The space is reserved, not used, until a decoder goes that deep.
const DECODER_STACK_BYTES: usize = 1 << 30;

/// Runs `f` on a thread pool with [`DECODER_STACK_BYTES`] stacks (its parallel iterators run
/// there too); on the calling thread when such a pool cannot be made.
pub(crate) fn deep_stack<T: Send>(f: impl FnOnce() -> T + Send) -> T {
    static POOL: OnceLock<Option<rayon::ThreadPool>> = OnceLock::new();
    let pool = POOL.get_or_init(|| {
        rayon::ThreadPoolBuilder::new()
            .stack_size(DECODER_STACK_BYTES)
            .thread_name(|i| format!("decoder {i}"))
            .build()
            .ok()
    });
    match pool {
        Some(pool) => pool.install(f),
        None => f(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_panic_becomes_its_message_and_results_pass_through() {
        assert_eq!(third_party(|| 7), Ok(7));
        let e = third_party(|| -> u8 { panic!("index out of bounds") }).unwrap_err();
        assert!(
            e.starts_with("the decoder failed on corrupt data (index out of bounds at "),
            "{e}"
        );
        let v: Vec<u32> = Vec::new();
        let e = third_party(|| v[3]).unwrap_err();
        assert!(e.contains("index out of bounds"), "{e}");
    }
}
