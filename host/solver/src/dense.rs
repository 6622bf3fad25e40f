//! Small dense least-squares problems (the classical tracker baselines):
//! Levenberg–Marquardt with a central-difference Jacobian.

/// Minimise ½‖f(x)‖² by Levenberg–Marquardt with a central-difference
/// Jacobian (small dense problems only). Returns x and the final ‖f‖².
pub fn dense_lm(
    mut x: Vec<f64>,
    f: &dyn Fn(&[f64]) -> Vec<f64>,
    max_iterations: usize,
) -> (Vec<f64>, f64) {
    let n = x.len();
    let mut r = f(&x);
    let mut cost: f64 = r.iter().map(|v| v * v).sum();
    let mut lambda = 1e-4;
    for _ in 0..max_iterations {
        let m = r.len();
        let mut jac = vec![0.0; m * n];
        for j in 0..n {
            let h = 1e-6 * (1.0 + x[j].abs());
            let mut xp = x.clone();
            xp[j] += h;
            let rp = f(&xp);
            xp[j] -= 2.0 * h;
            let rm = f(&xp);
            for i in 0..m {
                jac[i * n + j] = (rp[i] - rm[i]) / (2.0 * h);
            }
        }
        let mut jtj = vec![0.0; n * n];
        let mut jtr = vec![0.0; n];
        for i in 0..m {
            let row = &jac[i * n..(i + 1) * n];
            for a in 0..n {
                jtr[a] += row[a] * r[i];
                for b in 0..=a {
                    jtj[a * n + b] += row[a] * row[b];
                }
            }
        }
        let dmax = (0..n).map(|a| jtj[a * n + a]).fold(0.0, f64::max);
        let mut improved = false;
        for _ in 0..12 {
            let mut a = jtj.clone();
            for k in 0..n {
                a[k * n + k] += lambda * (jtj[k * n + k] + 1e-9 * dmax);
            }
            let Some(step) = cholesky_solve(&mut a, &jtr, n) else {
                lambda *= 10.0;
                continue;
            };
            let xn: Vec<f64> = x.iter().zip(&step).map(|(a, s)| a - s).collect();
            let rn = f(&xn);
            let cn: f64 = rn.iter().map(|v| v * v).sum();
            if cn.is_finite() && cn <= cost {
                let rel = (cost - cn) / cost.max(1e-300);
                x = xn;
                r = rn;
                cost = cn;
                lambda = (lambda / 10.0).max(1e-12);
                improved = rel > 1e-12;
                break;
            }
            lambda *= 10.0;
        }
        if !improved {
            break;
        }
    }
    (x, cost)
}

/// Solve the symmetric positive definite system (lower triangle of `a`
/// given, overwritten by its Cholesky factor); `None` when not positive definite.
pub fn cholesky_solve(a: &mut [f64], b: &[f64], n: usize) -> Option<Vec<f64>> {
    for i in 0..n {
        for j in 0..=i {
            let mut s = a[i * n + j];
            for k in 0..j {
                s -= a[i * n + k] * a[j * n + k];
            }
            if i == j {
                if s.is_nan() || s <= 0.0 {
                    return None;
                }
                a[i * n + i] = s.sqrt();
            } else {
                a[i * n + j] = s / a[j * n + j];
            }
        }
    }
    let mut y = b.to_vec();
    for i in 0..n {
        for k in 0..i {
            y[i] -= a[i * n + k] * y[k];
        }
        y[i] /= a[i * n + i];
    }
    for i in (0..n).rev() {
        for k in i + 1..n {
            y[i] -= a[k * n + i] * y[k];
        }
        y[i] /= a[i * n + i];
    }
    Some(y)
}
