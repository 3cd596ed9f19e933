//! Resource limits checked before anything is allocated or run: the number of steps and a
//! lower bound on the memory a mesh needs, and the plain number format of the messages.
//!
//! * Steps: at most [`MAX_STEPS`] (1e8). A step is at least one sparse solve and one history
//!   row, so 1e8 steps is days of computing and gigabytes of history.csv: more is a typing
//!   error (`time_step = 1e-300`), not a plan.
//! * Memory: [`memory_lower_bound`] counts the three sparse matrices every run holds (the
//!   stiffness, the mass and the factor of the iteration matrix, each at least the pattern's
//!   lower triangle: 8 bytes of value and 8 of index per entry), with the fewest neighbours
//!   any element kind of the dimension gives (7 nodes around a node of a triangle grid, 15 of a
//!   tetrahedron grid), plus what building the pattern holds at once: each cell's lower
//!   triangle as (row, column) pairs and the permutation that sums them, 24 bytes per entry
//!   ([`cell_triplets`]; 300 entries for a Hex8 cell: a 160^3 box needs 29 GB there alone).
//!   The factor's fill, the mesh and the work arrays come on top, so a scene over the bound
//!   certainly does not fit; it is compared with the whole physical memory ([`memory_limit`],
//!   /proc/meminfo's MemTotal, or 16 GiB where it cannot be read), not a fraction of it, so
//!   that nothing that might fit is refused. The generators are checked before they allocate
//!   (one body), the whole scene once its meshes are read (every body, Gmsh files too).

/// The largest number of steps a scene may ask for (end_time / time_step).
pub const MAX_STEPS: f64 = 1e8;

/// The physical memory assumed where it cannot be read (bytes).
pub const DEFAULT_MEMORY_LIMIT: f64 = 16.0 * 1024.0 * 1024.0 * 1024.0;

/// The steps `run` takes from 0 to `end_time` with `time_step` (the last one may be
/// shortened; a quotient that is an integer up to round-off, 0.07 / 0.01 =
/// 7.000000000000001, is not one more step). May be huge or infinite: compare it with
/// [`MAX_STEPS`] before using it as a count.
pub fn step_count(end_time: f64, time_step: f64) -> f64 {
    (end_time / time_step * (1.0 - 1e-9)).ceil().max(0.0)
}

/// Bytes per unknown that every run holds at least, in dimension `d` (see the module docs).
fn bytes_per_unknown(d: usize) -> f64 {
    // Coupled unknowns of a row: (neighbour nodes) x d; the lower triangle about half of them.
    let neighbours = if d == 2 { 7.0 } else { 15.0 };
    let lower = 0.5 * neighbours * d as f64 + 0.5;
    3.0 * 16.0 * lower
}

/// Bytes per cell-matrix entry while the pattern is built: the (row, column) pair and the
/// permutation entry that sums it into the pattern, held at once (`assembly::Pattern::new`).
const BYTES_PER_TRIPLET: f64 = 24.0;

/// Entries of the lower triangle of one cell's matrix, for a cell of `nodes` nodes in
/// dimension `d`.
pub fn cell_triplets(nodes: usize, d: usize) -> f64 {
    let n = (nodes * d) as f64;
    0.5 * n * (n + 1.0)
}

/// The fewest cell-matrix entries a generator's grid cell gives in dimension `d`: one
/// quadrilateral or hexahedron (its triangles or tetrahedra give more).
pub fn grid_cell_triplets(d: usize) -> f64 {
    cell_triplets(1 << d, d)
}

/// A lower bound on the memory (bytes) of a run with `unknowns` unknowns and `triplets`
/// cell-matrix entries ([`cell_triplets`] summed over the cells) in dimension `d`.
pub fn memory_lower_bound(unknowns: f64, triplets: f64, d: usize) -> f64 {
    unknowns * bytes_per_unknown(d) + triplets * BYTES_PER_TRIPLET
}

/// The memory a run may use (bytes): the machine's physical memory (Linux /proc/meminfo),
/// else [`DEFAULT_MEMORY_LIMIT`].
pub fn memory_limit() -> f64 {
    std::fs::read_to_string("/proc/meminfo")
        .ok()
        .and_then(|text| {
            let line = text.lines().find(|l| l.starts_with("MemTotal:"))?;
            let kib: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
            Some(kib * 1024.0)
        })
        .filter(|&b| b > 0.0)
        .unwrap_or(DEFAULT_MEMORY_LIMIT)
}

/// A number for a message: as written when short (0.75, 1e-4 as 0.0001), else in scientific
/// notation (1e308, not 309 digits; 1.2345678e-7).
pub fn plain(x: f64) -> String {
    let text = x.to_string();
    if text.len() <= 12 || !x.is_finite() {
        text
    } else {
        format!("{x:e}")
    }
}

/// Bytes for a message: `3.2e11 bytes (298 GiB)`.
pub fn bytes(b: f64) -> String {
    format!(
        "{:.1e} bytes ({:.0} GiB)",
        b,
        b / (1024.0 * 1024.0 * 1024.0)
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plain_numbers_are_short() {
        assert_eq!(plain(0.75), "0.75");
        assert_eq!(plain(1e-4), "0.0001");
        assert_eq!(plain(1e308), "1e308");
        assert_eq!(plain(1e-300), "1e-300");
        assert_eq!(plain(f64::NAN), "NaN");
    }

    #[test]
    fn steps_and_memory() {
        assert_eq!(step_count(0.07, 0.01), 7.0);
        assert_eq!(step_count(0.075, 0.01), 8.0);
        assert!(step_count(0.01, 1e-300) > MAX_STEPS);
        // A 2D grid of 1e8 nodes: 2e8 unknowns hold at least 7.2e10 bytes of matrices.
        assert_eq!(memory_lower_bound(2e8, 0.0, 2), 2e8 * 360.0);
        // A Hex8 cell's 24 unknowns: 300 entries of the lower triangle; a Quad4's 36.
        assert_eq!((cell_triplets(8, 3), grid_cell_triplets(3)), (300.0, 300.0));
        assert_eq!(grid_cell_triplets(2), 36.0);
        // The box of 160^3 Hex8 cells whose `check` asked for one 19.7 GB allocation (the
        // pattern's pairs alone): 29.5 GB counted now, beyond a 24 GiB machine.
        let cells = 160f64.powi(3);
        let bound = memory_lower_bound(161f64.powi(3) * 3.0, cells * 300.0, 3);
        assert!(bound > 24.0 * 1024f64.powi(3), "{bound:e}");
        assert!(memory_limit() > 0.0);
    }
}
