//! Encoder noise: a small deterministic Gaussian generator.

use super::Joints;

/// Small deterministic Gaussian generator (SplitMix64 + Box–Muller).
#[derive(Debug)]
pub(crate) struct Noise {
    pub(crate) state: u64,
}

impl Noise {
    /// Uniform in (0, 1).
    pub(crate) fn uniform(&mut self) -> f64 {
        self.state = self.state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.state;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        ((z >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }

    /// Standard normal.
    pub(crate) fn gaussian(&mut self) -> f64 {
        let (u1, u2) = (self.uniform(), self.uniform());
        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    }

    /// `q` as an encoder reports it: plus noise of standard deviation
    /// `sd[i]` on joint `i` (drawn in joint order).
    pub(crate) fn measure(&mut self, q: Joints, sd: &Joints) -> Joints {
        let mut q = q;
        for (qi, s) in q.iter_mut().zip(sd) {
            *qi += s * self.gaussian();
        }
        q
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gaussian_has_unit_variance() {
        let mut n = Noise { state: 7 };
        let xs: Vec<f64> = (0..20000).map(|_| n.gaussian()).collect();
        let mean = xs.iter().sum::<f64>() / xs.len() as f64;
        let var = xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / xs.len() as f64;
        assert!(
            mean.abs() < 0.03 && (var - 1.0).abs() < 0.05,
            "{mean} {var}"
        );
    }
}
