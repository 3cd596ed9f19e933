//! What the examples share: small statistics (the figure printers) and the command line and
//! recording of the runnable examples (`run`).
#![allow(dead_code)] // each example uses its own subset

pub mod run;

/// The median (upper middle for an even count); NaN for no samples.
pub fn median(mut v: Vec<f64>) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// The process's peak resident memory so far (bytes): `VmHWM` of `/proc/self/status`; `None`
/// where there is no such file (not Linux).
pub fn peak_resident_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}

/// One line on memory: the process's peak against the linear solver's factor, the figure the
/// performance issue's target is set on ("peak memory within 2x the factor's size").
pub fn memory_line(memory: &softway::simulation::SolverMemory) -> String {
    let mib = |b: f64| b / (1024.0 * 1024.0);
    let factor = memory.factor as f64;
    let mut line = format!(
        "memory: factor values {:.1} MiB, kept contact factors {:.1} MiB, stored matrices {:.1} MiB",
        mib(factor),
        mib(memory.contact_factors as f64),
        mib(memory.matrices as f64)
    );
    match peak_resident_bytes() {
        Some(peak) => line.push_str(&format!(
            "; peak resident {:.1} MiB = {:.2}x the factor",
            mib(peak as f64),
            peak as f64 / factor
        )),
        None => line.push_str("; peak resident: not measured (no /proc/self/status)"),
    }
    line
}

/// The arithmetic mean; NaN for no samples.
pub fn mean(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len() as f64
}

/// A Hex8 unit cube of `n`^3 cells of rubber (E = 1e7 Pa, nu = 0.3, rho = 1000 kg/m^3) and its
/// iteration matrix `M/h + (alpha^2 h/2) K` at h = 1 ms, on the lower-triangle pattern M and K
/// share (the matrix the ordering and thread reports factor).
pub fn cube_iteration_matrix(n: usize) -> softway::Result<faer::sparse::SparseColMat<usize, f64>> {
    use softway::prelude::*;
    let mesh = cuboid(
        nalgebra::Vector3::zeros(),
        nalgebra::Vector3::new(1.0, 1.0, 1.0),
        [n, n, n],
        ElementKind::Hex8,
    )?;
    let rubber = Material::LinearElastic(LinearElastic::new(1e7, 0.3, 1000.0)?);
    let h = 1e-3;
    let sim = Simulation3::builder()
        .time_step(h)
        .body(Body::new("box", mesh, rubber))
        .build()?;
    let alpha = sim.settings().scheme.alpha;
    let (m, k) = (sim.mass_matrix(), sim.stiffness_matrix());
    let values: Vec<f64> = m
        .values()
        .iter()
        .zip(k.values())
        .map(|(m, k)| m / h + 0.5 * alpha * alpha * h * k)
        .collect();
    let pattern = faer::sparse::SymbolicSparseColMat::new_checked(
        m.size(),
        m.size(),
        m.column_starts().to_vec(),
        None,
        m.row_indices().to_vec(),
    );
    Ok(faer::sparse::SparseColMat::new(pattern, values))
}
