//! The Nelder–Mead simplex minimiser (derivative-free), for the axis calibration.

// ---- Nelder–Mead ---------------------------------------------------------------------------

/// Options of [`nelder_mead`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct NelderMeadOptions {
    /// Most iterations (one reflection and what follows it).
    pub(crate) max_iterations: u32,
    /// Stop when the simplex's values span less than this.
    pub(crate) f_tol: f64,
    /// ... and its vertices lie within this distance of the best one (∞-norm).
    pub(crate) x_tol: f64,
}

impl Default for NelderMeadOptions {
    fn default() -> Self {
        Self {
            max_iterations: 200,
            f_tol: 1e-9,
            x_tol: 1e-4,
        }
    }
}

/// The result of [`nelder_mead`].
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Minimum {
    /// The best point found.
    pub(crate) x: Vec<f64>,
    /// The function's value there.
    pub(crate) value: f64,
    /// Iterations run.
    pub(crate) iterations: u32,
    /// Function evaluations.
    pub evaluations: u32,
}

/// Minimises `f` by the Nelder–Mead simplex method (standard coefficients: reflection 1,
/// expansion 2, contraction ½, shrink ½), from `x0` with an initial simplex of `x0` and
/// `x0 + step[i]·eᵢ`. Derivative-free, so it copes with the robust, piecewise-smooth
/// alignment cost. Non-finite values count as +∞.
///
/// # Panics
/// When `x0` and `step` differ in length or are empty.
///
/// ```text
/// use voxoct_depth::{nelder_mead, NelderMeadOptions};
/// let m = nelder_mead(
///     |x| (x[0] - 1.0).powi(2) + 10.0 * (x[1] + 2.0).powi(2),
///     &[0.0, 0.0],
///     &[0.5, 0.5],
///     &NelderMeadOptions::default(),
/// );
/// assert!((m.x[0] - 1.0).abs() < 1e-3 && (m.x[1] + 2.0).abs() < 1e-3);
/// ```
pub(crate) fn nelder_mead(
    mut f: impl FnMut(&[f64]) -> f64,
    x0: &[f64],
    step: &[f64],
    opts: &NelderMeadOptions,
) -> Minimum {
    assert!(
        !x0.is_empty() && x0.len() == step.len(),
        "x0 and step must be non-empty and of one length"
    );
    let n = x0.len();
    let mut evals = 0u32;
    let mut eval = |x: &[f64]| {
        evals += 1;
        let v = f(x);
        if v.is_finite() { v } else { f64::INFINITY }
    };
    let mut simplex: Vec<(Vec<f64>, f64)> = Vec::with_capacity(n + 1);
    simplex.push((x0.to_vec(), eval(x0)));
    for i in 0..n {
        let mut x = x0.to_vec();
        x[i] += step[i];
        let v = eval(&x);
        simplex.push((x, v));
    }
    let mut iterations = 0;
    let lerp = |a: &[f64], b: &[f64], t: f64| -> Vec<f64> {
        a.iter().zip(b).map(|(a, b)| a + t * (b - a)).collect()
    };
    while iterations < opts.max_iterations {
        simplex.sort_by(|a, b| a.1.total_cmp(&b.1));
        let spread = simplex[n].1 - simplex[0].1;
        let size = simplex[1..]
            .iter()
            .flat_map(|(x, _)| x.iter().zip(&simplex[0].0).map(|(a, b)| (a - b).abs()))
            .fold(0.0, f64::max);
        if spread.abs() <= opts.f_tol && size <= opts.x_tol {
            break;
        }
        iterations += 1;
        let mut centroid = vec![0.0; n];
        for (x, _) in &simplex[..n] {
            for (c, xi) in centroid.iter_mut().zip(x) {
                *c += xi / n as f64;
            }
        }
        let worst = simplex[n].clone();
        let xr = lerp(&centroid, &worst.0, -1.0);
        let fr = eval(&xr);
        if fr < simplex[0].1 {
            let xe = lerp(&centroid, &worst.0, -2.0);
            let fe = eval(&xe);
            simplex[n] = if fe < fr { (xe, fe) } else { (xr, fr) };
        } else if fr < simplex[n - 1].1 {
            simplex[n] = (xr, fr);
        } else {
            let (xc, fc) = if fr < worst.1 {
                let xc = lerp(&centroid, &xr, 0.5);
                let fc = eval(&xc);
                (xc, fc)
            } else {
                let xc = lerp(&centroid, &worst.0, 0.5);
                let fc = eval(&xc);
                (xc, fc)
            };
            if fc < worst.1.min(fr) {
                simplex[n] = (xc, fc);
            } else {
                let best = simplex[0].0.clone();
                for v in simplex.iter_mut().skip(1) {
                    v.0 = lerp(&best, &v.0, 0.5);
                    v.1 = eval(&v.0);
                }
            }
        }
    }
    simplex.sort_by(|a, b| a.1.total_cmp(&b.1));
    let (x, value) = simplex.swap_remove(0);
    Minimum {
        x,
        value,
        iterations,
        evaluations: evals,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nelder_mead_minimises_rosenbrock_and_a_robust_bowl() {
        let rosen = |x: &[f64]| (1.0 - x[0]).powi(2) + 100.0 * (x[1] - x[0] * x[0]).powi(2);
        let opts = NelderMeadOptions {
            max_iterations: 2000,
            f_tol: 1e-14,
            x_tol: 1e-8,
        };
        let m = nelder_mead(rosen, &[-1.2, 1.0], &[0.5, 0.5], &opts);
        assert!(
            (m.x[0] - 1.0).abs() < 1e-3 && (m.x[1] - 1.0).abs() < 1e-3,
            "{m:?}"
        );
        assert!(m.evaluations > m.iterations);
        // A saturating (Geman–McClure) bowl in three variables with a NaN region.
        let f = |x: &[f64]| {
            if x[2] > 50.0 {
                return f64::NAN;
            }
            let r2: f64 = x
                .iter()
                .zip([3.0, -2.0, 0.5])
                .map(|(a, b)| (a - b).powi(2))
                .sum();
            r2 / (r2 + 4.0)
        };
        let m = nelder_mead(f, &[0.0; 3], &[2.0; 3], &NelderMeadOptions::default());
        assert!(m.value < 1e-6, "{m:?}");
    }
}
