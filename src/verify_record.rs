//! The measured figures of the book's verification chapter (`python3 book/verification.py`).
//!
//! A test calls `record(row, quantity, value)` with the figure its assertion bounds, just
//! before the assertion. When the environment variable `SOFTWAY_VERIFY_OUT` names a file, one
//! line `row<TAB>quantity<TAB>value` is appended to it, written with a single call (tests run
//! in parallel threads and processes); unset, nothing is written. One source for both users:
//! the library's unit tests (`#[cfg(test)]` in `lib.rs`) and the integration tests, which
//! include this file as `common::verify` (`#[path]` in `tests/common/mod.rs`).

use std::io::Write;
use std::path::PathBuf;
use std::sync::OnceLock;

/// The file named by `SOFTWAY_VERIFY_OUT`, read once per process.
fn destination() -> Option<&'static PathBuf> {
    static OUT: OnceLock<Option<PathBuf>> = OnceLock::new();
    OUT.get_or_init(|| {
        std::env::var_os("SOFTWAY_VERIFY_OUT")
            .filter(|p| !p.is_empty())
            .map(PathBuf::from)
    })
    .as_ref()
}

/// Appends `row<TAB>quantity<TAB>value` to the file named by `SOFTWAY_VERIFY_OUT`, if any:
/// `row` is the key of a row of `book/src/verification.md`, `quantity` one of the names its
/// key comment lists.
pub fn record(row: &str, quantity: &str, value: f64) {
    let Some(path) = destination() else {
        return;
    };
    assert!(
        !format!("{row}{quantity}").contains(['\t', '\n']),
        "verification record {row:?} {quantity:?}: no tab or newline"
    );
    let line = format!("{row}\t{quantity}\t{value:e}\n");
    std::fs::OpenOptions::new()
        .create(true)
        .append(true)
        .open(path)
        .and_then(|mut file| file.write_all(line.as_bytes()))
        .unwrap_or_else(|e| panic!("SOFTWAY_VERIFY_OUT {}: {e}", path.display()));
}
