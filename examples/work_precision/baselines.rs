//! The two baselines of `work_precision`, written here on the library's own mass and
//! stiffness matrices: central difference (lumped mass, kinematic contact) and Newmark average
//! acceleration (consistent mass, a Lagrange multiplier per wall node). See `main.rs`.

// Index loops over the unknowns read as the formulas do.
#![allow(clippy::needless_range_loop)]

use super::common::run::Failure;
use super::{bar, end_time, h_crit, Outcome, GAP, L, V0};
use softway::prelude::*;

/// A symmetric matrix copied out of the library's view: lower triangle, compressed columns.
#[derive(Debug, Clone)]
pub struct Sym {
    pub n: usize,
    col_ptr: Vec<usize>,
    row_idx: Vec<usize>,
    values: Vec<f64>,
}

impl Sym {
    pub fn of(view: softway::simulation::SymmetricMatrix<'_>) -> Sym {
        Sym {
            n: view.size(),
            col_ptr: view.column_starts().to_vec(),
            row_idx: view.row_indices().to_vec(),
            values: view.values().to_vec(),
        }
    }

    /// `y = A x`.
    pub fn mul_into(&self, x: &[f64], y: &mut [f64]) {
        y.fill(0.0);
        for j in 0..self.n {
            for k in self.col_ptr[j]..self.col_ptr[j + 1] {
                let i = self.row_idx[k];
                y[i] += self.values[k] * x[j];
                if i != j {
                    y[j] += self.values[k] * x[i];
                }
            }
        }
    }

    pub fn dot(&self, x: &[f64], y: &[f64]) -> f64 {
        let mut ay = vec![0.0; self.n];
        self.mul_into(y, &mut ay);
        x.iter().zip(&ay).map(|(a, b)| a * b).sum()
    }

    /// Row sums (the lumped mass of a consistent mass matrix).
    pub fn row_sums(&self) -> Vec<f64> {
        let mut y = vec![0.0; self.n];
        self.mul_into(&vec![1.0; self.n], &mut y);
        y
    }

    /// Every stored entry `(row, column, value)`, row >= column.
    pub fn entries(&self) -> impl Iterator<Item = (usize, usize, f64)> + '_ {
        (0..self.n).flat_map(move |j| {
            (self.col_ptr[j]..self.col_ptr[j + 1])
                .map(move |k| (self.row_idx[k], j, self.values[k]))
        })
    }
}

/// The bar's discretisation as the library assembles it, for the baselines.
#[derive(Debug, Clone)]
pub struct Discrete {
    pub mass: Sym,
    pub stiffness: Sym,
    pub lumped: Vec<f64>,
    /// The x unknowns of the nodes on the wall side and their reference x [m].
    pub wall_dofs: Vec<(usize, f64)>,
    /// The wall's x [m].
    pub wall: f64,
    /// Each node's reference x, per unknown (the banded ordering).
    pub dof_x: Vec<f64>,
    pub total_mass: f64,
}

impl Discrete {
    pub fn new() -> Result<Discrete, Failure> {
        let sim = bar(ContactMethod::SoftWay, h_crit())?;
        let mass = Sym::of(sim.mass_matrix());
        let stiffness = Sym::of(sim.stiffness_matrix());
        let lumped = mass.row_sums();
        let x = sim.reference_positions();
        let wall_dofs = (0..x.len())
            .filter(|&a| (x[a][0] - L).abs() < 1e-12)
            .map(|a| (2 * a, x[a][0]))
            .collect();
        let dof_x = (0..2 * x.len()).map(|i| x[i / 2][0]).collect();
        let total_mass = lumped.iter().step_by(2).sum();
        Ok(Discrete {
            mass,
            stiffness,
            lumped,
            wall_dofs,
            wall: L + GAP,
            dof_x,
            total_mass,
        })
    }

    pub fn initial_velocity(&self) -> Vec<f64> {
        (0..self.mass.n)
            .map(|i| ((i + 1) % 2) as f64 * V0)
            .collect()
    }

    pub fn initial_energy(&self) -> f64 {
        0.5 * self.total_mass * V0 * V0
    }

    /// Velocity of the centre of mass along x for the lumped masses.
    pub fn mean_velocity(&self, v: &[f64]) -> f64 {
        (0..v.len())
            .step_by(2)
            .map(|i| self.lumped[i] * v[i])
            .sum::<f64>()
            / self.total_mass
    }

    /// `2 / omega_max` of `M_lumped^-1 K` (power iteration): the lumped mesh's stable step.
    pub fn lumped_stable_step(&self) -> f64 {
        let n = self.mass.n;
        let mut x: Vec<f64> = (0..n).map(|i| ((i * 7919) % 13) as f64 - 6.0).collect();
        let mut y = vec![0.0; n];
        let mut lambda = 0.0;
        for _ in 0..3000 {
            self.stiffness.mul_into(&x, &mut y);
            for i in 0..n {
                y[i] /= self.lumped[i];
            }
            let norm = y.iter().map(|a| a * a).sum::<f64>().sqrt();
            let xn = x.iter().map(|a| a * a).sum::<f64>().sqrt();
            lambda = norm / xn;
            x.iter_mut().zip(&y).for_each(|(a, b)| *a = b / norm);
        }
        2.0 / lambda.sqrt()
    }
}

/// Central difference with lumped mass at step h, the wall a kinematic constraint.
pub fn central_difference(d: &Discrete, h: f64) -> Outcome {
    let n = d.mass.n;
    let mut u = vec![0.0; n];
    let mut u_new = vec![0.0; n];
    // v_{n+1/2}; a_0 = 0 (the bar starts unstrained), so v_{1/2} = v0.
    let mut v = d.initial_velocity();
    let mut f = vec![0.0; n];
    let mut forces = Vec::new();
    let end = end_time(h);
    let mut t = 0.0;
    let mut energy = d.initial_energy();
    while t < end {
        d.stiffness.mul_into(&u, &mut f);
        for i in 0..n {
            v[i] -= h * f[i] / d.lumped[i];
            u_new[i] = u[i] + h * v[i];
        }
        let mut force = 0.0;
        for &(i, x) in &d.wall_dofs {
            let p = x + u_new[i] - d.wall;
            if p > 0.0 {
                force += d.lumped[i] * p / (h * h);
                v[i] -= p / h;
                u_new[i] -= p;
            }
        }
        forces.push(force);
        energy = 0.5 * d.lumped.iter().zip(&v).map(|(m, v)| m * v * v).sum::<f64>()
            + 0.5 * d.stiffness.dot(&u, &u_new);
        std::mem::swap(&mut u, &mut u_new);
        t += h;
    }
    Outcome::from_forces(&forces, h, energy / d.initial_energy(), d.mean_velocity(&v))
}

/// A symmetric positive definite band matrix, its Cholesky factor in place (rows of the lower
/// band, `width + 1` entries each), on unknowns permuted by `order`.
pub struct Band {
    pub n: usize,
    width: usize,
    /// `l[i * (width + 1) + (j + width - i)]` = L(i, j), i - width <= j <= i.
    l: Vec<f64>,
    /// New position of each original unknown.
    position: Vec<usize>,
}

impl Band {
    /// Factors `a M + K` with the unknowns ordered along the bar.
    pub fn factor(d: &Discrete, a: f64) -> Band {
        let n = d.mass.n;
        let mut order: Vec<usize> = (0..n).collect();
        order.sort_by(|&p, &q| d.dof_x[p].total_cmp(&d.dof_x[q]).then(p.cmp(&q)));
        let mut position = vec![0; n];
        for (new, &old) in order.iter().enumerate() {
            position[old] = new;
        }
        let entries = || {
            d.mass
                .entries()
                .map(move |(i, j, m)| (i, j, a * m))
                .chain(d.stiffness.entries())
                .map(|(i, j, v)| {
                    let (p, q) = (position[i], position[j]);
                    (p.max(q), p.min(q), v)
                })
        };
        let width = entries().map(|(p, q, _)| p - q).max().unwrap_or(0);
        let w1 = width + 1;
        let mut l = vec![0.0; n * w1];
        for (p, q, v) in entries() {
            l[p * w1 + q + width - p] += v;
        }
        for i in 0..n {
            for j in i.saturating_sub(width)..=i {
                let lo = i.saturating_sub(width).max(j.saturating_sub(width));
                let mut s = l[i * w1 + j + width - i];
                for k in lo..j {
                    s -= l[i * w1 + k + width - i] * l[j * w1 + k + width - j];
                }
                l[i * w1 + j + width - i] = if i == j {
                    s.sqrt()
                } else {
                    s / l[j * w1 + width]
                };
            }
        }
        Band {
            n,
            width,
            l,
            position,
        }
    }

    /// `x = A^-1 b` (`work`: scratch of size n).
    pub fn solve(&self, b: &[f64], x: &mut [f64], work: &mut [f64]) {
        let (w, w1) = (self.width, self.width + 1);
        for (old, &new) in self.position.iter().enumerate() {
            work[new] = b[old];
        }
        for i in 0..self.n {
            let mut s = work[i];
            for k in i.saturating_sub(w)..i {
                s -= self.l[i * w1 + k + w - i] * work[k];
            }
            work[i] = s / self.l[i * w1 + w];
        }
        for i in (0..self.n).rev() {
            let mut s = work[i];
            for k in i + 1..(i + w1).min(self.n) {
                s -= self.l[k * w1 + i + w - k] * work[k];
            }
            work[i] = s / self.l[i * w1 + w];
        }
        for (old, &new) in self.position.iter().enumerate() {
            x[old] = work[new];
        }
    }
}

/// Newmark average acceleration on the consistent mass at step h; the wall a Lagrange
/// multiplier per wall node (active set, Schur complement on the factored matrix); `reset`:
/// the held nodes' normal velocity and acceleration set to zero after the step.
pub fn newmark(d: &Discrete, h: f64, reset: bool) -> Outcome {
    let n = d.mass.n;
    let c = 4.0 / (h * h);
    let band = Band::factor(d, c);
    let mut work = vec![0.0; n];
    // A^-1 e_j for each wall unknown.
    let columns: Vec<Vec<f64>> = d
        .wall_dofs
        .iter()
        .map(|&(i, _)| {
            let mut e = vec![0.0; n];
            e[i] = 1.0;
            let mut x = vec![0.0; n];
            band.solve(&e, &mut x, &mut work);
            x
        })
        .collect();
    let nc = d.wall_dofs.len();
    let mut u = vec![0.0; n];
    let mut v = d.initial_velocity();
    let mut a = vec![0.0; n];
    let mut free = vec![0.0; n];
    let mut y = vec![0.0; n];
    let mut rhs = vec![0.0; n];
    let mut forces = Vec::new();
    let end = end_time(h);
    let mut t = 0.0;
    while t < end {
        for i in 0..n {
            y[i] = c * u[i] + 4.0 / h * v[i] + a[i];
        }
        d.mass.mul_into(&y, &mut rhs);
        band.solve(&rhs, &mut free, &mut work);
        // Active set: lambda >= 0 pushes the node back (force -lambda along x).
        let mut active = vec![false; nc];
        let mut lambda = vec![0.0; nc];
        for _ in 0..4 * nc + 2 {
            let set: Vec<usize> = (0..nc).filter(|&j| active[j]).collect();
            lambda.fill(0.0);
            if !set.is_empty() {
                // G lambda = penetration of the free solution, G_jk = (A^-1 e_k)_(dof j).
                let m = set.len();
                let mut g = nalgebra::DMatrix::zeros(m, m);
                let mut p = nalgebra::DVector::zeros(m);
                for (r, &j) in set.iter().enumerate() {
                    let (dof, x) = d.wall_dofs[j];
                    p[r] = x + free[dof] - d.wall;
                    for (s, &k) in set.iter().enumerate() {
                        g[(r, s)] = columns[k][dof];
                    }
                }
                let l = g.lu().solve(&p).expect("the Schur complement is definite");
                for (r, &j) in set.iter().enumerate() {
                    lambda[j] = l[r];
                }
            }
            let position = |j: usize| {
                let (dof, x) = d.wall_dofs[j];
                x + free[dof] - (0..nc).map(|k| lambda[k] * columns[k][dof]).sum::<f64>()
            };
            // Release the most tensile, else add the deepest penetration, else done.
            let tensile = (0..nc)
                .filter(|&j| active[j] && lambda[j] < 0.0)
                .min_by(|&p, &q| lambda[p].total_cmp(&lambda[q]));
            let through = (0..nc)
                .filter(|&j| !active[j] && position(j) > d.wall + 1e-15)
                .max_by(|&p, &q| position(p).total_cmp(&position(q)));
            match (tensile, through) {
                (Some(j), _) => active[j] = false,
                (None, Some(j)) => active[j] = true,
                (None, None) => break,
            }
        }
        let mut force = 0.0;
        for i in 0..n {
            let mut u1 = free[i];
            for k in 0..nc {
                u1 -= lambda[k] * columns[k][i];
            }
            let a1 = c * (u1 - u[i]) - 4.0 / h * v[i] - a[i];
            v[i] += 0.5 * h * (a[i] + a1);
            a[i] = a1;
            u[i] = u1;
        }
        for (j, l) in lambda.iter().enumerate() {
            force += l;
            if reset && *l > 0.0 {
                let dof = d.wall_dofs[j].0;
                v[dof] = 0.0;
                a[dof] = 0.0;
            }
        }
        forces.push(force);
        t += h;
    }
    let energy = 0.5 * d.mass.dot(&v, &v) + 0.5 * d.stiffness.dot(&u, &u);
    let ones: Vec<f64> = (0..n).map(|i| ((i + 1) % 2) as f64).collect();
    let exit = d.mass.dot(&ones, &v) / d.mass.dot(&ones, &ones);
    Outcome::from_forces(&forces, h, energy / d.initial_energy(), exit)
}
