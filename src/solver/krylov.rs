//! Krylov solvers on a matrix-free operator with a preconditioner: conjugate gradients for the
//! symmetric iteration matrix, flexible GMRES for the iteration matrix with non-symmetric
//! rank-one terms. Both are preconditioned by a sparse Cholesky factorisation of a nearby
//! matrix (`simulation::linear_solve` chooses it).

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// The residual norm a solve stops at: `target`, never below 1e-10 |b|; `None` when b = 0
/// (x = 0 solves it exactly).
fn stopping_norm(b: &[f64], target: f64) -> Option<f64> {
    let b_norm = dot(b, b).sqrt();
    (b_norm != 0.0).then(|| target.max(1e-10 * b_norm))
}

/// `b - apply(x)`.
fn residual(apply: &dyn Fn(&[f64]) -> Vec<f64>, b: &[f64], x: &[f64]) -> Vec<f64> {
    b.iter().zip(apply(x)).map(|(b, a)| b - a).collect()
}

/// Preconditioned conjugate gradients on `apply(x) = b` until the residual norm is at most
/// `target` (never below 1e-10 |b|): the solution and its residual
/// `b - apply(x)`; `None` if that takes more than `max` iterations.
pub(crate) fn conjugate_gradients(
    apply: &dyn Fn(&[f64]) -> Vec<f64>,
    precondition: &dyn Fn(&mut [f64]),
    b: &[f64],
    target: f64,
    max: usize,
) -> Option<(Vec<f64>, Vec<f64>)> {
    let n = b.len();
    let Some(target) = stopping_norm(b, target) else {
        return Some((vec![0.0; n], vec![0.0; n]));
    };
    let mut x = b.to_vec();
    precondition(&mut x);
    let mut r = residual(apply, b, &x);
    // Each residual is tested before it is preconditioned: a converged solve makes no
    // preconditioner solve it does not use (one in three of a one-iteration solve's).
    if dot(&r, &r).sqrt() <= target {
        return Some((x, r));
    }
    let mut z = r.clone();
    precondition(&mut z);
    let mut p = z.clone();
    let mut rz = dot(&r, &z);
    for _ in 0..max {
        let ap = apply(&p);
        let alpha = rz / dot(&p, &ap);
        if !alpha.is_finite() || alpha <= 0.0 {
            return None;
        }
        for i in 0..n {
            x[i] += alpha * p[i];
            r[i] -= alpha * ap[i];
        }
        if dot(&r, &r).sqrt() <= target {
            return Some((x, r));
        }
        z.copy_from_slice(&r);
        precondition(&mut z);
        let rz_next = dot(&r, &z);
        let beta = rz_next / rz;
        rz = rz_next;
        for i in 0..n {
            p[i] = z[i] + beta * p[i];
        }
    }
    None
}

/// Flexible GMRES (no restart) on `apply(x) = b` from `start`, right-preconditioned by
/// `precondition`, until the residual norm is at most `target` (never below 1e-10 |b|): the solution and its
/// residual `b - apply(x)`; `None` if that takes more than `max` iterations. Flexible: the
/// preconditioned directions are kept, so a single-precision preconditioner, whose solve is
/// linear only to its round-off, leaves the computed residual the true one. For an operator
/// that is not symmetric (a factored symmetric matrix plus `m` rank-one terms, the
/// preconditioner's low-rank difference), it converges in about as many iterations as that
/// rank.
pub(crate) fn flexible_gmres(
    apply: &dyn Fn(&[f64]) -> Vec<f64>,
    precondition: &dyn Fn(&mut [f64]),
    b: &[f64],
    start: Vec<f64>,
    target: f64,
    max: usize,
) -> Option<(Vec<f64>, Vec<f64>)> {
    let n = b.len();
    let Some(target) = stopping_norm(b, target) else {
        return Some((vec![0.0; n], vec![0.0; n]));
    };
    let mut x = start;
    let r = residual(apply, b, &x);
    let beta = dot(&r, &r).sqrt();
    if beta <= target {
        return Some((x, r));
    }
    // Arnoldi basis `v`, preconditioned directions `z`, Hessenberg columns `h` reduced to
    // upper triangular by the Givens rotations `(c, s)`, and the rotated right-hand side `g`.
    let mut v: Vec<Vec<f64>> = vec![r.iter().map(|x| x / beta).collect()];
    let mut z: Vec<Vec<f64>> = Vec::new();
    let mut h: Vec<Vec<f64>> = Vec::new();
    let mut rotations: Vec<(f64, f64)> = Vec::new();
    let mut g = vec![beta];
    for j in 0..max {
        let mut zj = v[j].clone();
        precondition(&mut zj);
        let mut w = apply(&zj);
        z.push(zj);
        // Modified Gram-Schmidt, twice (the basis stays orthogonal to round-off).
        let mut column = vec![0.0; j + 2];
        for _ in 0..2 {
            for (i, vi) in v.iter().enumerate() {
                let hij = dot(&w, vi);
                column[i] += hij;
                for (wk, vk) in w.iter_mut().zip(vi) {
                    *wk -= hij * vk;
                }
            }
        }
        let norm = dot(&w, &w).sqrt();
        column[j + 1] = norm;
        for (i, &(c, s)) in rotations.iter().enumerate() {
            let (a, b) = (column[i], column[i + 1]);
            column[i] = c * a + s * b;
            column[i + 1] = -s * a + c * b;
        }
        let (a, b) = (column[j], column[j + 1]);
        let radius = a.hypot(b);
        if !(radius > 0.0) || !radius.is_finite() {
            return None;
        }
        let (c, s) = (a / radius, b / radius);
        column[j] = radius;
        column[j + 1] = 0.0;
        rotations.push((c, s));
        g.push(-s * g[j]);
        g[j] *= c;
        h.push(column);
        let estimate = g[j + 1].abs();
        if estimate <= target || norm <= f64::EPSILON * beta {
            break;
        }
        v.push(w.iter().map(|x| x / norm).collect());
    }
    // y = R^-1 g, then x += Z y.
    let k = h.len();
    let mut y = vec![0.0; k];
    for i in (0..k).rev() {
        let sum: f64 = (i + 1..k).map(|l| h[l][i] * y[l]).sum();
        y[i] = (g[i] - sum) / h[i][i];
    }
    for (zl, yl) in z.iter().zip(&y) {
        for (xi, zi) in x.iter_mut().zip(zl) {
            *xi += yl * zi;
        }
    }
    let r = residual(apply, b, &x);
    (dot(&r, &r).sqrt() <= target).then_some((x, r))
}

#[cfg(test)]
mod tests {
    use super::{conjugate_gradients, flexible_gmres};
    use nalgebra::{DMatrix, DVector};
    use std::cell::Cell;

    /// Preconditioned by a single-precision factor of the matrix itself, CG reaches 1e-12 in
    /// a few iterations, and makes one preconditioner solve per iteration plus the start's:
    /// none for the residual it returns.
    #[test]
    fn conjugate_gradients_preconditions_no_residual_it_returns() {
        let n = 50;
        let (symmetric, _, b) = coupled_system(n);
        let cholesky = symmetric.clone().cholesky().expect("positive definite");
        let (products, solves) = (Cell::new(0), Cell::new(0));
        let apply = |x: &[f64]| {
            products.set(products.get() + 1);
            (&symmetric * DVector::from_column_slice(x))
                .as_slice()
                .to_vec()
        };
        let precondition = |r: &mut [f64]| {
            solves.set(solves.get() + 1);
            let x = cholesky.solve(&DVector::from_column_slice(r));
            for (ri, xi) in r.iter_mut().zip(x.iter()) {
                *ri = f64::from(*xi as f32);
            }
        };
        let target = 1e-12 * b.norm();
        let (x, residual) = conjugate_gradients(&apply, &precondition, b.as_slice(), target, 10)
            .expect("converges");
        let true_residual = &b - &symmetric * DVector::from_vec(x);
        assert!(
            true_residual.norm() <= 2.0 * target,
            "{}",
            true_residual.norm()
        );
        assert!((DVector::from_vec(residual) - true_residual).norm() <= 1e-14 * b.norm());
        // The start's residual, then one product per iteration; one solve for the start and
        // one per iteration but the last.
        let iterations = products.get() - 1;
        assert!((1..=3).contains(&iterations), "{iterations} iterations");
        assert_eq!(solves.get(), iterations + 1);
        // Out of iterations (the start alone is a single-precision solve): no answer.
        assert!(conjugate_gradients(&apply, &precondition, b.as_slice(), target, 0).is_none());
    }

    /// A symmetric positive definite tridiagonal matrix plus three non-symmetric rank-one
    /// terms, as the implicit-projection tangent with held normals that turn.
    fn coupled_system(n: usize) -> (DMatrix<f64>, DMatrix<f64>, DVector<f64>) {
        let symmetric = DMatrix::from_fn(n, n, |i, j| match i.abs_diff(j) {
            0 => 4.0 + i as f64 / n as f64,
            1 => -1.0,
            _ => 0.0,
        });
        let mut full = symmetric.clone();
        for k in 0..3 {
            let u = DVector::from_fn(n, |i, _| ((i * (k + 2)) % 7) as f64 - 3.0);
            let v = DVector::from_fn(n, |i, _| if i % (k + 3) == 0 { 0.5 } else { 0.0 });
            full += &u * v.transpose();
        }
        let b = DVector::from_fn(n, |i, _| (i as f64).sin());
        (symmetric, full, b)
    }

    #[test]
    fn flexible_gmres_solves_a_symmetric_matrix_plus_rank_one_terms_in_rank_plus_one_iterations() {
        let n = 40;
        let (symmetric, full, b) = coupled_system(n);
        let exact = full.clone().lu().solve(&b).expect("regular");
        let cholesky = symmetric.clone().cholesky().expect("positive definite");
        let apply = |x: &[f64]| (&full * DVector::from_column_slice(x)).as_slice().to_vec();
        let precondition = |r: &mut [f64]| {
            let x = cholesky.solve(&DVector::from_column_slice(r));
            r.copy_from_slice(x.as_slice());
        };
        let target = 1e-10 * b.norm();
        // Preconditioned by the symmetric part, the operator is the identity plus rank 3: at
        // most four iterations (two are not enough here).
        let start = || {
            let mut x = b.as_slice().to_vec();
            precondition(&mut x);
            x
        };
        assert!(flexible_gmres(&apply, &precondition, b.as_slice(), start(), target, 2).is_none());
        let (x, residual) = flexible_gmres(&apply, &precondition, b.as_slice(), start(), target, 4)
            .expect("converges");
        let x = DVector::from_vec(x);
        let true_residual = &b - &full * &x;
        assert!(true_residual.norm() <= target, "{}", true_residual.norm());
        assert!((DVector::from_vec(residual) - true_residual).norm() <= 1e-14 * b.norm());
        assert!((x - exact).norm() <= 1e-9 * b.norm());
    }

    /// A preconditioner rounded to single precision is linear only to its round-off; the
    /// flexible variant keeps its directions, so the residual it reports is the true one.
    #[test]
    fn flexible_gmres_with_a_single_precision_preconditioner_reaches_the_target() {
        let n = 60;
        let (symmetric, full, b) = coupled_system(n);
        let cholesky = symmetric.cholesky().expect("positive definite");
        let apply = |x: &[f64]| (&full * DVector::from_column_slice(x)).as_slice().to_vec();
        let precondition = |r: &mut [f64]| {
            let x = cholesky.solve(&DVector::from_column_slice(r));
            for (ri, xi) in r.iter_mut().zip(x.iter()) {
                *ri = f64::from(*xi as f32);
            }
        };
        let target = 1e-10 * b.norm();
        let start = vec![0.0; n];
        let (x, _) = flexible_gmres(&apply, &precondition, b.as_slice(), start, target, 20)
            .expect("converges");
        let true_residual = &b - &full * DVector::from_vec(x);
        assert!(true_residual.norm() <= target, "{}", true_residual.norm());
    }
}
