//! The chip's internal sampling in datasheet mode ([`crate::ChipModel::Datasheet`]).
//!
//! In a non-fusion mode (AMG) the accelerometer and the gyroscope each run
//! on their own internal clock at an output data rate (ODR) that their
//! configured bandwidth implies, low-pass filter the signal at that
//! bandwidth, and write the filtered value to the data registers once per
//! internal period; a register holds its value until the next update.
//!
//! Facts used (BNO055 datasheet BST-BNO055-DS000 tables 3-4, 3-8, 3-9 and
//! §4.3; the BNO055's accelerometer is a BMA280-class part, its gyroscope a
//! BMG160-class part, whose own datasheets give the rates):
//!
//! | `ACC_Config` bits 4:2 | 0 | 1 | 2 | 3 | 4 | 5 | 6 | 7 |
//! |---|---|---|---|---|---|---|---|---|
//! | bandwidth, Hz | 7.81 | 15.63 | 31.25 | **62.5** | 125 | 250 | 500 | 1000 |
//! | ODR (2 × bandwidth), Hz | 15.625 | 31.25 | 62.5 | **125** | 250 | 500 | 1000 | 2000 |
//!
//! | `GYR_Config_0` bits 5:3 | 0 | 1 | 2 | 3 | 4 | 5 | 6 | 7 |
//! |---|---|---|---|---|---|---|---|---|
//! | bandwidth, Hz | 523 | 230 | 116 | 47 | 23 | 12 | 64 | **32** |
//! | ODR, Hz | 2000 | 2000 | 1000 | 400 | 200 | 100 | 200 | **100** |
//!
//! (bold: the power-on defaults, 62.5 Hz / ±4 g and 32 Hz / ±2000 °/s).
//! Ranges: `ACC_Config` bits 1:0 ±2/4/8/16 g; `GYR_Config_0` bits 2:0
//! ±2000/1000/500/250/125 °/s. Units (`UNIT_SEL`): 100 LSB per m/s² or
//! 1 LSB per mg; 16 LSB per °/s or 900 LSB per rad/s; 1 LSB per °C or
//! 2 LSB per °F.
//!
//! **Assumed where the datasheet is silent.** The filter type: two identical
//! first-order low-pass sections in cascade (critically damped second
//! order), continuous in time, with the −3 dB frequency at the configured
//! bandwidth: each section's time constant is T = √(√2 − 1) / (2π f_bw), so
//! the group delay at low frequency is exactly [`Timing::group_delay_s`] =
//! 2T ≈ 1.287 / (2π f_bw) (3.28 ms at 62.5 Hz, 6.40 ms at 32 Hz, 1.77 ms
//! at 116 Hz). The internal clocks tick at multiples of 1/(ODR·(1 + ε))
//! from the source's time zero, ε the chip clock's error
//! ([`crate::Bno055Sim::with_clock_error_ppm`], default 0: no drift
//! relative to the source's clock; the filter, taken as continuous, does
//! not scale with it); the input
//! between two stimuli is linear in time (the filter is solved exactly for
//! it); saturation and
//! quantisation apply to the filtered value (plus the source's output noise)
//! when it is written to the registers.

/// Accelerometer or gyroscope.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Sensor {
    /// The accelerometer (`ACC_DATA`).
    Accel,
    /// The gyroscope (`GYR_DATA`).
    Gyro,
}

/// One sensor's configured timing.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Timing {
    /// Low-pass bandwidth (−3 dB), Hz.
    pub bandwidth_hz: f64,
    /// Internal output data rate, Hz.
    pub odr_hz: f64,
}

/// Filter sections in cascade.
const SECTIONS: usize = 2;

impl Timing {
    /// The accelerometer's timing for an `ACC_Config` value (bits 4:2).
    pub fn accel(acc_config: u8) -> Self {
        let bandwidth_hz = match (acc_config >> 2) & 0x07 {
            0 => 7.8125,
            1 => 15.625,
            2 => 31.25,
            3 => 62.5,
            4 => 125.0,
            5 => 250.0,
            6 => 500.0,
            _ => 1000.0,
        };
        Self {
            bandwidth_hz,
            odr_hz: 2.0 * bandwidth_hz,
        }
    }

    /// The gyroscope's timing for a `GYR_Config_0` value (bits 5:3).
    pub fn gyro(gyr_config_0: u8) -> Self {
        let (bandwidth_hz, odr_hz) = match (gyr_config_0 >> 3) & 0x07 {
            0 => (523.0, 2000.0),
            1 => (230.0, 2000.0),
            2 => (116.0, 1000.0),
            3 => (47.0, 400.0),
            4 => (23.0, 200.0),
            5 => (12.0, 100.0),
            6 => (64.0, 200.0),
            _ => (32.0, 100.0),
        };
        Self {
            bandwidth_hz,
            odr_hz,
        }
    }

    /// Time constant of each of the two filter sections, s.
    pub fn section_time_constant_s(&self) -> f64 {
        libm::sqrt(core::f64::consts::SQRT_2 - 1.0) / (core::f64::consts::TAU * self.bandwidth_hz)
    }

    /// The filter's group delay at low frequency (a ramp's lag), s.
    pub fn group_delay_s(&self) -> f64 {
        SECTIONS as f64 * self.section_time_constant_s()
    }
}

/// Accelerometer full scale for an `ACC_Config` value (bits 1:0), m/s².
pub(crate) fn accel_full_scale_mps2(acc_config: u8) -> f64 {
    let g = match acc_config & 0x03 {
        0 => 2.0,
        1 => 4.0,
        2 => 8.0,
        _ => 16.0,
    };
    g * STANDARD_GRAVITY
}

/// Gyroscope full scale for a `GYR_Config_0` value (bits 2:0; 5..7 read as
/// 125 °/s), rad/s.
pub(crate) fn gyro_full_scale_rads(gyr_config_0: u8) -> f64 {
    let dps = match gyr_config_0 & 0x07 {
        0 => 2000.0,
        1 => 1000.0,
        2 => 500.0,
        3 => 250.0,
        _ => 125.0,
    };
    dps * core::f64::consts::PI / 180.0
}

/// Standard gravity, m/s² (the mg unit).
pub(crate) const STANDARD_GRAVITY: f64 = 9.80665;

/// Counts per SI unit for `UNIT_SEL`: (accelerometer per m/s², gyroscope per rad/s).
pub(crate) fn counts_per_unit(unit_sel: u8) -> (f64, f64) {
    let accel = if unit_sel & 0x01 == 0 {
        100.0
    } else {
        1000.0 / STANDARD_GRAVITY
    };
    let gyro = if unit_sel & 0x02 == 0 {
        16.0 * 180.0 / core::f64::consts::PI
    } else {
        900.0
    };
    (accel, gyro)
}

/// The `TEMP` register for a die temperature (`UNIT_SEL` bit 4: °F at 2 LSB).
pub(crate) fn temp_counts(unit_sel: u8, temp_c: f64) -> i8 {
    let value = if unit_sel & 0x10 == 0 {
        temp_c
    } else {
        2.0 * (temp_c * 1.8 + 32.0)
    };
    libm::round(value).clamp(-128.0, 127.0) as i8
}

/// `value` (SI) saturated at ±`full_scale` and rounded to counts.
pub fn to_counts(value: f64, counts_per_unit: f64, full_scale: f64) -> i16 {
    // (the epsilon keeps e.g. 250 °/s × 16 LSB exactly 4000)
    let limit = libm::floor(full_scale * counts_per_unit + 1e-6).min(f64::from(i16::MAX));
    libm::round(value * counts_per_unit).clamp(-limit, limit) as i16
}

/// One axis's filter: two identical first-order sections in cascade,
/// integrated exactly for an input linear in time over each step.
#[derive(Debug, Clone, Copy, PartialEq)]
struct AxisFilter {
    y: [f64; SECTIONS],
}

impl AxisFilter {
    fn settled(x: f64) -> Self {
        Self { y: [x; SECTIONS] }
    }

    /// Advances by `h` s with the input going linearly from `x0` to `x1`
    /// (slope r): y₁' = (x − y₁)/T, y₂' = (y₁ − y₂)/T solved exactly. The
    /// particular solution is x − rT, x − 2rT; the deviations e₁, e₂ from it
    /// decay as e₁(s) = e₁(0)·e^{−s/T}, e₂(s) = (e₂(0) + e₁(0)·s/T)·e^{−s/T}.
    fn step(&mut self, h: f64, x0: f64, x1: f64, tc: f64) {
        if h <= 0.0 {
            return;
        }
        let rt = (x1 - x0) / h * tc;
        let a = libm::exp(-h / tc);
        let e1 = self.y[0] - (x0 - rt);
        let e2 = self.y[1] - (x0 - 2.0 * rt);
        self.y[0] = x1 - rt + e1 * a;
        self.y[1] = x1 - 2.0 * rt + (e2 + e1 * h / tc) * a;
    }

    fn output(&self) -> f64 {
        self.y[SECTIONS - 1]
    }
}

/// One sensor's pipeline: three filters, the internal clock, and the last
/// input seen.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Pipeline {
    timing: Timing,
    /// The internal update rate on the source's clock, ODR·(1 + ε), Hz.
    rate_hz: f64,
    axes: [AxisFilter; 3],
    /// Index k of the next internal update, at k / `rate_hz`.
    next_update: u64,
    /// Time and input the filters have reached.
    t: f64,
    x: [f64; 3],
    updates: u64,
}

impl Pipeline {
    /// A pipeline starting at time `t` with input `x`, its filters settled
    /// there, its clock running (1 + `clock_error`) fast.
    pub(crate) fn start(timing: Timing, clock_error: f64, t: f64, x: [f64; 3]) -> Self {
        let rate_hz = timing.odr_hz * (1.0 + clock_error);
        Self {
            timing,
            rate_hz,
            axes: x.map(AxisFilter::settled),
            next_update: libm::floor(t * rate_hz) as u64 + 1,
            t,
            x,
            updates: 0,
        }
    }

    pub(crate) fn timing(&self) -> Timing {
        self.timing
    }

    /// Register updates so far.
    pub(crate) fn updates(&self) -> u64 {
        self.updates
    }

    /// Runs to time `t` with input `x` (linear from the last input),
    /// calling `update` with the filtered vector at every internal tick in
    /// between.
    pub(crate) fn run_to(&mut self, t: f64, x: [f64; 3], mut update: impl FnMut([f64; 3])) {
        if t <= self.t {
            return;
        }
        let tc = self.timing.section_time_constant_s();
        let (t0, x0) = (self.t, self.x);
        loop {
            let tick = self.next_update as f64 / self.rate_hz;
            if tick > t {
                break;
            }
            let w = (tick - t0) / (t - t0);
            let xk: [f64; 3] = core::array::from_fn(|i| x0[i] + w * (x[i] - x0[i]));
            self.advance(tick, xk, tc);
            update(self.axes.map(|a| a.output()));
            self.updates += 1;
            self.next_update += 1;
        }
        self.advance(t, x, tc);
    }

    fn advance(&mut self, t: f64, x: [f64; 3], tc: f64) {
        let h = t - self.t;
        for ((axis, x0), x1) in self.axes.iter_mut().zip(self.x).zip(x) {
            axis.step(h, x0, x1, tc);
        }
        self.t = t;
        self.x = x;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The sections' exact solution against a fine step-by-step integration
    /// of y' = (x − y)/T (midpoint inputs) for a smooth input: an
    /// independent reference.
    #[test]
    fn the_filter_step_matches_a_fine_numerical_integration() {
        let tc = 2e-3;
        let x = |t: f64| libm::sin(300.0 * t) + 0.5 * t;
        let mut f = AxisFilter::settled(x(0.0));
        let (mut y1, mut y2) = (x(0.0), x(0.0));
        let h = 2.5e-4;
        let fine = 2000;
        for k in 0..400 {
            let t0 = k as f64 * h;
            f.step(h, x(t0), x(t0 + h), tc);
            for j in 0..fine {
                let dt = h / fine as f64;
                let t = t0 + (j as f64 + 0.5) * dt;
                // midpoint of the linear input over the coarse step, as the filter sees it
                let w = (t - t0) / h;
                let xin = x(t0) + w * (x(t0 + h) - x(t0));
                let g = -libm::expm1(-dt / tc);
                let y1_mid = y1 + 0.5 * g * (xin - y1);
                y1 += g * (xin - y1);
                y2 += g * (y1_mid - y2);
            }
            assert!((f.y[0] - y1).abs() < 1e-7, "k={k}: {} vs {y1}", f.y[0]);
            assert!(
                (f.output() - y2).abs() < 1e-7,
                "k={k}: {} vs {y2}",
                f.output()
            );
        }
    }
}
