//! Device time → session time, from `Ping` echoes.
//!
//! Each echo gives the host's send and receive times (session clock, s) and
//! the device clock when the device handled the ping (µs, unwrapped). The
//! device handled it somewhere between send and receive; the midpoint is
//! the estimate, good to half the round trip. The mapping is a line,
//!
//! ```text
//! t_device = offset + (1 + drift) · t_host
//! ```
//!
//! fitted robustly: echoes with a round trip above the median are dropped
//! (queued behind other traffic, their midpoint is biased), then least
//! squares with residuals beyond 5 × the median absolute deviation
//! removed until none is (a reboot's stray echo, a scheduler hiccup).

/// One `Ping` → `Pong` exchange.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Echo {
    /// Host time when the ping was sent, s (session clock).
    pub host_send: f64,
    /// Host time when the pong arrived, s (session clock).
    pub host_recv: f64,
    /// Device time when the ping was handled, s (unwrapped device clock).
    pub device: f64,
}

impl Echo {
    /// The round trip, s.
    pub fn rtt(&self) -> f64 {
        self.host_recv - self.host_send
    }

    fn host_mid(&self) -> f64 {
        0.5 * (self.host_send + self.host_recv)
    }
}

/// A fitted device-to-session clock mapping.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ClockFit {
    /// Device time at session time 0, s.
    pub offset: f64,
    /// Rate error of the device clock (positive: it runs fast), unitless.
    pub drift: f64,
    /// RMS of the inlier residuals, s.
    pub residual_rms: f64,
    /// Echoes used / given.
    pub used: usize,
    /// Echoes given.
    pub total: usize,
}

impl ClockFit {
    /// Session time of device time `device` (s).
    pub fn to_session(&self, device: f64) -> f64 {
        (device - self.offset) / (1.0 + self.drift)
    }

    /// Drift in parts per million.
    pub fn drift_ppm(&self) -> f64 {
        self.drift * 1e6
    }

    /// Fits `echoes`; `None` with fewer than two usable echoes (or all at
    /// one instant). With exactly one usable echo a caller may fall back to
    /// [`ClockFit::offset_only`].
    pub fn fit(echoes: &[Echo]) -> Option<ClockFit> {
        let good: Vec<&Echo> = echoes
            .iter()
            .filter(|e| e.rtt().is_finite() && e.rtt() >= 0.0 && e.device.is_finite())
            .collect();
        if good.len() < 2 {
            return None;
        }
        let mut rtts: Vec<f64> = good.iter().map(|e| e.rtt()).collect();
        rtts.sort_by(f64::total_cmp);
        let rtt_cut = rtts[rtts.len() / 2];
        let points: Vec<(f64, f64)> = good
            .iter()
            .filter(|e| e.rtt() <= rtt_cut)
            .map(|e| (e.host_mid(), e.device))
            .collect();
        let (a, b, used) = robust_line(points, 2)?;
        let ss: f64 = used.iter().map(|(x, y)| (y - (a + b * x)).powi(2)).sum();
        Some(ClockFit {
            offset: a,
            drift: b - 1.0,
            residual_rms: (ss / used.len() as f64).sqrt(),
            used: used.len(),
            total: echoes.len(),
        })
    }

    /// A mapping with no drift through one echo (the first second of a
    /// recording, before a second echo has come back).
    pub fn offset_only(echo: &Echo) -> ClockFit {
        ClockFit {
            offset: echo.device - echo.host_mid(),
            drift: 0.0,
            residual_rms: 0.5 * echo.rtt(),
            used: 1,
            total: 1,
        }
    }
}

/// A fitted line y = a + b·x and the points of its last fit.
pub(super) type RobustLine = (f64, f64, Vec<(f64, f64)>);

/// Least-squares line through `points`, dropping those beyond 5 MAD of the
/// residuals and refitting until none is (or fewer than `min_keep` would
/// stay): intercept, slope and the points of the last fit.
pub(super) fn robust_line(mut points: Vec<(f64, f64)>, min_keep: usize) -> Option<RobustLine> {
    loop {
        let (a, b) = line(&points)?;
        let res: Vec<f64> = points.iter().map(|(x, y)| y - (a + b * x)).collect();
        let mut abs: Vec<f64> = res.iter().map(|r| r.abs()).collect();
        abs.sort_by(f64::total_cmp);
        let mad = abs[abs.len() / 2].max(1e-7);
        let keep: Vec<(f64, f64)> = points
            .iter()
            .zip(&res)
            .filter(|(_, r)| r.abs() <= 5.0 * mad)
            .map(|(p, _)| *p)
            .collect();
        if keep.len() == points.len() || keep.len() < min_keep {
            return Some((a, b, points));
        }
        points = keep;
    }
}

/// Least-squares line y = a + b·x (centred for conditioning).
pub(super) fn line(points: &[(f64, f64)]) -> Option<(f64, f64)> {
    let n = points.len() as f64;
    let mx = points.iter().map(|p| p.0).sum::<f64>() / n;
    let my = points.iter().map(|p| p.1).sum::<f64>() / n;
    let sxx: f64 = points.iter().map(|p| (p.0 - mx).powi(2)).sum();
    let sxy: f64 = points.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    if sxx <= 0.0 {
        return None;
    }
    let b = sxy / sxx;
    Some((my - b * mx, b))
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    /// Echoes of a clock 2.5 s ahead running 48.7 ppm fast, with random
    /// round trips and handling instants, a few long stalls and two stray
    /// echoes: the fit recovers offset and drift to the jitter's precision.
    #[test]
    fn fit_recovers_offset_and_drift_despite_outliers() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(3);
        let (offset, drift) = (2.5, 48.7e-6);
        let mut echoes = Vec::new();
        for k in 0..600 {
            let send = 0.1 * k as f64 + 0.01 * rng.random::<f64>();
            let stall = if k % 97 == 5 { 0.05 } else { 0.0 };
            let rtt = 2e-4 + 2e-4 * rng.random::<f64>() + stall;
            let handled = send + rtt * rng.random::<f64>();
            echoes.push(Echo {
                host_send: send,
                host_recv: send + rtt,
                device: offset + (1.0 + drift) * handled,
            });
        }
        echoes[100].device += 30.0;
        echoes[400].device -= 0.3;
        let fit = ClockFit::fit(&echoes).unwrap();
        assert!((fit.offset - offset).abs() < 3e-5, "offset {}", fit.offset);
        assert!(
            (fit.drift_ppm() - 48.7).abs() < 0.5,
            "drift {}",
            fit.drift_ppm()
        );
        assert!(fit.residual_rms < 2e-4);
        assert!(fit.used < 600);
        // Session time of a device instant, inverted exactly.
        let t = fit.to_session(offset + (1.0 + drift) * 30.0);
        assert!((t - 30.0).abs() < 1e-4, "t {t}");
    }

    #[test]
    fn too_few_echoes_give_no_fit() {
        let e = Echo {
            host_send: 1.0,
            host_recv: 1.001,
            device: 5.0,
        };
        assert!(ClockFit::fit(&[e]).is_none());
        assert!(ClockFit::fit(&[e, e]).is_none());
        let f = ClockFit::offset_only(&e);
        assert!((f.to_session(5.0) - 1.0005).abs() < 1e-12);
    }
}
