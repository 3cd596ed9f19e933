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

/// The arithmetic mean; NaN for no samples.
pub fn mean(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len() as f64
}
