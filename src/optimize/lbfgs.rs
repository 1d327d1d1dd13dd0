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
    let mut history = History::default();
    let mut d = vec![0.0; n];
    let mut trial = vec![0.0; n];
    let mut g_new = vec![0.0; n];
    let mut small = 0;
    for it in 0..max_iterations {
        let Some(slope) = history.descent(&g, &mut d, first_step) else {
            return Minimised { iterations: it, value };
        };
        let Some((t, v_new)) = line_search(f, x, &d, value, slope, &mut trial, &mut g_new) else {
            return Minimised { iterations: it, value };
        };
        let s: Vec<f64> = d.iter().map(|d| t * d).collect();
        let y: Vec<f64> = g_new.iter().zip(&g).map(|(a, b)| a - b).collect();
        let sy = dot(&s, &y);
        x.copy_from_slice(&trial);
        std::mem::swap(&mut g, &mut g_new);
        let decrease = value - v_new;
        value = v_new;
        history.remember(s, y, sy);
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

/// The last [`MEMORY`] pairs (s, y) of steps and gradient changes, with ρ = 1 / sᵀy.
#[derive(Default)]
struct History {
    s: Vec<Vec<f64>>,
    y: Vec<Vec<f64>>,
    rho: Vec<f64>,
}

impl History {
    /// Write the search direction into `d` and return its slope gᵀd, or None if g vanishes.
    fn descent(&mut self, g: &[f64], d: &mut [f64], first_step: f64) -> Option<f64> {
        self.two_loop(g, d, first_step)?;
        let mut slope = dot(g, d);
        if slope.is_nan() || slope >= 0.0 {
            // Not a descent direction: restart from steepest descent.
            self.s.clear();
            self.y.clear();
            self.rho.clear();
            let gmax = max_abs(g);
            if gmax.is_nan() || gmax <= 0.0 {
                return None;
            }
            d.iter_mut().zip(g).for_each(|(d, g)| *d = -g * first_step / gmax);
            slope = dot(g, d);
        }
        Some(slope)
    }

    /// Two-loop recursion d = −H g; with no pairs, −g scaled to `first_step` (None if g vanishes).
    fn two_loop(&self, g: &[f64], d: &mut [f64], first_step: f64) -> Option<()> {
        let mut alpha_buf = [0.0; MEMORY];
        d.iter_mut().zip(g).for_each(|(d, g)| *d = -g);
        let m = self.s.len();
        for k in (0..m).rev() {
            let a = self.rho[k] * dot(&self.s[k], d);
            alpha_buf[k] = a;
            axpy(-a, &self.y[k], d);
        }
        if m > 0 {
            let gamma = dot(&self.s[m - 1], &self.y[m - 1]) / dot(&self.y[m - 1], &self.y[m - 1]);
            d.iter_mut().for_each(|v| *v *= gamma);
        } else {
            let dmax = max_abs(d);
            if dmax.is_nan() || dmax <= 0.0 {
                return None;
            }
            let scale = first_step / dmax;
            d.iter_mut().for_each(|v| *v *= scale);
        }
        for k in 0..m {
            let b = self.rho[k] * dot(&self.y[k], d);
            axpy(alpha_buf[k] - b, &self.s[k], d);
        }
        Some(())
    }

    /// Keep the pair (s, y) if its curvature sᵀy = `sy` is positive, dropping the oldest beyond [`MEMORY`].
    fn remember(&mut self, s: Vec<f64>, y: Vec<f64>, sy: f64) {
        if sy > 1e-300 {
            if self.s.len() == MEMORY {
                self.s.remove(0);
                self.y.remove(0);
                self.rho.remove(0);
            }
            self.s.push(s);
            self.y.push(y);
            self.rho.push(1.0 / sy);
        }
    }
}

/// Backtracking line search along `d`: step t and energy at `trial` = x + t d (gradient in `g_new`), or None.
fn line_search(
    f: &mut Energy,
    x: &[f64],
    d: &[f64],
    value: f64,
    slope: f64,
    trial: &mut [f64],
    g_new: &mut [f64],
) -> Option<(f64, f64)> {
    let mut t = 1.0;
    for _ in 0..MAX_BACKTRACKS {
        trial.iter_mut().zip(x.iter()).zip(d).for_each(|((y, x), d)| *y = x + t * d);
        g_new.iter_mut().for_each(|v| *v = 0.0);
        if let Some(v) = f(trial, g_new) {
            if v <= value + ARMIJO * t * slope {
                return Some((t, v));
            }
        }
        t *= 0.5;
    }
    None
}

/// The largest absolute value in `v` (0 for none).
fn max_abs(v: &[f64]) -> f64 {
    v.iter().fold(0.0f64, |a, v| a.max(v.abs()))
}

/// The dot product aᵀb.
fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(a, b)| a * b).sum()
}

/// y += a x.
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
