//! Limited-memory BFGS with a backtracking (Armijo) line search, for energies
//! that are infinite outside a feasible set: a trial point where the energy
//! is infinite is treated as too long a step, so the iterates never leave
//! the set they start in (the barrier phase of [`super`] keeps every sample
//! point valid this way).

/// Pairs (s, y) kept.
const MEMORY: usize = 8;

/// Armijo constant of sufficient decrease.
const ARMIJO: f64 = 1e-4;

/// Halvings of a trial step before the search gives up.
const MAX_BACKTRACKS: usize = 40;

/// An energy: the value at x with its gradient written into the second
/// argument, or None where the energy is infinite.
pub type Energy<'a> = dyn FnMut(&[f64], &mut [f64]) -> Option<f64> + 'a;

/// How a minimisation ended.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Minimised {
    pub iterations: usize,
    /// The energy at the returned point.
    pub value: f64,
}

/// Minimise `f` from `x` (which must be feasible: `f` finite there), in
/// place. `f(x, grad)` returns the energy and writes its gradient, or None
/// where the energy is infinite. The first step moves the variable that
/// moves most by `first_step`. Stops after `max_iterations`, or when an
/// iteration lowers the energy by less than `rel_tol` times its value, or
/// when no step along the search direction lowers it.
pub fn minimise(x: &mut [f64], f: &mut Energy, first_step: f64, max_iterations: usize, rel_tol: f64) -> Minimised {
    let n = x.len();
    let mut g = vec![0.0; n];
    let Some(mut value) = f(x, &mut g) else {
        return Minimised { iterations: 0, value: f64::INFINITY };
    };
    let (mut s_hist, mut y_hist, mut rho): (Vec<Vec<f64>>, Vec<Vec<f64>>, Vec<f64>) = (vec![], vec![], vec![]);
    let mut d = vec![0.0; n];
    let mut trial = vec![0.0; n];
    let mut g_new = vec![0.0; n];
    let mut alpha_buf = [0.0; MEMORY];
    let mut small = 0;
    for it in 0..max_iterations {
        // Two-loop recursion: d = −H g.
        d.iter_mut().zip(&g).for_each(|(d, g)| *d = -g);
        let m = s_hist.len();
        for k in (0..m).rev() {
            let a = rho[k] * dot(&s_hist[k], &d);
            alpha_buf[k] = a;
            axpy(-a, &y_hist[k], &mut d);
        }
        if m > 0 {
            let gamma = dot(&s_hist[m - 1], &y_hist[m - 1]) / dot(&y_hist[m - 1], &y_hist[m - 1]);
            d.iter_mut().for_each(|v| *v *= gamma);
        } else {
            let dmax = d.iter().fold(0.0f64, |a, v| a.max(v.abs()));
            if dmax.is_nan() || dmax <= 0.0 {
                return Minimised { iterations: it, value };
            }
            let scale = first_step / dmax;
            d.iter_mut().for_each(|v| *v *= scale);
        }
        for k in 0..m {
            let b = rho[k] * dot(&y_hist[k], &d);
            axpy(alpha_buf[k] - b, &s_hist[k], &mut d);
        }
        let mut slope = dot(&g, &d);
        if slope.is_nan() || slope >= 0.0 {
            // Not a descent direction: restart from steepest descent.
            s_hist.clear();
            y_hist.clear();
            rho.clear();
            let gmax = g.iter().fold(0.0f64, |a, v| a.max(v.abs()));
            if gmax.is_nan() || gmax <= 0.0 {
                return Minimised { iterations: it, value };
            }
            d.iter_mut().zip(&g).for_each(|(d, g)| *d = -g * first_step / gmax);
            slope = dot(&g, &d);
        }
        // Backtracking line search.
        let mut t = 1.0;
        let mut accepted = None;
        for _ in 0..MAX_BACKTRACKS {
            trial.iter_mut().zip(x.iter()).zip(&d).for_each(|((y, x), d)| *y = x + t * d);
            g_new.iter_mut().for_each(|v| *v = 0.0);
            if let Some(v) = f(&trial, &mut g_new) {
                if v <= value + ARMIJO * t * slope {
                    accepted = Some(v);
                    break;
                }
            }
            t *= 0.5;
        }
        let Some(v_new) = accepted else {
            return Minimised { iterations: it, value };
        };
        let s: Vec<f64> = d.iter().map(|d| t * d).collect();
        let y: Vec<f64> = g_new.iter().zip(&g).map(|(a, b)| a - b).collect();
        let sy = dot(&s, &y);
        x.copy_from_slice(&trial);
        std::mem::swap(&mut g, &mut g_new);
        let decrease = value - v_new;
        value = v_new;
        if sy > 1e-300 {
            if s_hist.len() == MEMORY {
                s_hist.remove(0);
                y_hist.remove(0);
                rho.remove(0);
            }
            s_hist.push(s);
            y_hist.push(y);
            rho.push(1.0 / sy);
        }
        // Stop after three consecutive negligible decreases.
        if decrease <= rel_tol * value.abs() {
            small += 1;
            if small >= 3 {
                return Minimised { iterations: it + 1, value };
            }
        } else {
            small = 0;
        }
    }
    Minimised { iterations: max_iterations, value }
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(a, b)| a * b).sum()
}

fn axpy(a: f64, x: &[f64], y: &mut [f64]) {
    y.iter_mut().zip(x).for_each(|(y, x)| *y += a * x);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn minimises_the_rosenbrock_function() {
        let mut x = vec![-1.2, 1.0];
        let mut f = |x: &[f64], g: &mut [f64]| {
            let (a, b) = (x[0], x[1]);
            g[0] = -2.0 * (1.0 - a) - 400.0 * a * (b - a * a);
            g[1] = 200.0 * (b - a * a);
            Some((1.0 - a).powi(2) + 100.0 * (b - a * a).powi(2))
        };
        let r = minimise(&mut x, &mut f, 0.1, 500, 1e-16);
        assert!((x[0] - 1.0).abs() < 1e-5 && (x[1] - 1.0).abs() < 1e-5, "{x:?} {r:?}");
    }

    #[test]
    fn never_steps_where_the_energy_is_infinite() {
        // min of (x − 2)² over the barrier x < 1: iterates stay below 1.
        let mut x = vec![0.0];
        let mut f = |x: &[f64], g: &mut [f64]| {
            if x[0] >= 1.0 {
                return None;
            }
            g[0] = 2.0 * (x[0] - 2.0) + 1.0 / (1.0 - x[0]);
            Some((x[0] - 2.0).powi(2) - (1.0 - x[0]).ln())
        };
        let r = minimise(&mut x, &mut f, 0.5, 200, 1e-15);
        // Stationary point: 2(x − 2)(1 − x) + 1 = 0 → x = (3 − √3)/2.
        let exact = (3.0 - 3f64.sqrt()) / 2.0;
        assert!(x[0] < 1.0 && (x[0] - exact).abs() < 1e-6, "{x:?} {r:?}");
    }
}
