//! The scene loader with `--set` overrides: the input is a scene file whose first line may
//! hold overrides (`# --set K=V --set K=V`, as in `fixtures/fuzz/scenes/`). A scene that
//! loads is built and, when small, stepped once. Any panic is a finding, and so is an error
//! message that is empty or shows a Rust type.
#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;
use softway::dim::{Dim, SpatialDim};
use softway::io::scene;

const LEAKS: [&str; 6] = [
    "Scalar(",
    "struct ",
    "enum ",
    "Some(",
    "NonPositivePivot",
    "{ index",
];

/// `input` is the scene text: a parse error quotes the offending line, so a leak counts only
/// when the input does not hold the same text.
fn clean(message: String, input: &str) {
    assert!(!message.trim().is_empty(), "an empty error message");
    for leak in LEAKS {
        assert!(
            !message.contains(leak) || input.contains(leak),
            "the message shows `{leak}`: {message}"
        );
    }
}

fn build<const D: usize>(loaded: &scene::LoadedScene) -> Result<(), String>
where
    Dim<D>: SpatialDim<D>,
{
    let built = loaded.build::<D>().map_err(|e| e.to_string())?;
    let mut sim = built.simulation().map_err(|e| e.to_string())?;
    if sim.node_count() <= 3000 {
        sim.step().map_err(|e| e.to_string())?;
    }
    Ok(())
}

fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    let sets: Vec<String> = text
        .lines()
        .next()
        .and_then(|l| l.strip_prefix("# --set "))
        .map(|l| {
            l.split(" --set ")
                .filter(|s| !s.is_empty())
                .map(str::to_string)
                .collect()
        })
        .unwrap_or_default();
    // Mesh files named by the scene are looked up beside the bundled scenes.
    let path = Path::new("fixtures/scenes/fuzz.toml");
    let outcome = scene::parse(path, &text, &sets)
        .map_err(|e| e.to_string())
        .and_then(
            |loaded| match loaded.dimension().map_err(|e| e.to_string())? {
                2 => build::<2>(&loaded),
                _ => build::<3>(&loaded),
            },
        );
    if let Err(message) = outcome {
        clean(message, &text);
    }
});
