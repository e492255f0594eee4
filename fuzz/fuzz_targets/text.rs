#![no_main]

// The first byte picks the extension, so the `.pts` count line and every extension's path run.
libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let Some((&pick, rest)) = data.split_first() else {
        return;
    };
    let extension = ["xyz", "txt", "pts", "csv"][usize::from(pick % 4)];
    surfel_fuzz::load(extension, rest)
});
