//! Saturation found in the samples themselves, when no device range is
//! recorded (a pose session's IMU, any other tool's recording): a clipped
//! channel sits at one value, its extreme, for a run of samples. Runs of
//! at least `CLIP_RUN` identical samples at the channel's largest |value|
//! (within 98 % of it) are counted per channel,
//! when that value is at least `MIN_FULL_SCALE` of the sensor (no device
//! clips below 2 g or 125 °/s: an accelerometer at rest repeating 9.81 is
//! not saturated); a value near a typical full scale is named as such.

use super::channels::{saturation_severity, G_STANDARD, SATURATION};
use super::Finding;
use robimu_session::{Table, IMU_COLUMNS};

/// A clipped stretch is at least this many identical samples in a row.
pub(crate) const CLIP_RUN: usize = 5;
/// The smallest full scale of the accelerometer (m/s²) and the gyroscope
/// (rad/s): 2 g and 125 °/s (the BNO055's smallest ranges).
pub(crate) const MIN_FULL_SCALE: [f64; 2] =
    [2.0 * G_STANDARD, 125.0 * std::f64::consts::PI / 180.0];
/// Typical full scales (BNO055: 2, 4, 8, 16 g; 125…2000 °/s; other MEMS
/// parts up to 4000 °/s), in g and °/s.
const FULL_SCALES: [&[f64]; 2] = [
    &[2.0, 4.0, 6.0, 8.0, 12.0, 16.0, 24.0, 30.0],
    &[125.0, 250.0, 300.0, 500.0, 1000.0, 2000.0, 4000.0],
];
/// A value within this part of a typical full scale is named as at it.
const FULL_SCALE_TOLERANCE: f64 = 0.03;

/// The clipped samples of each channel of an IMU table `name`: one finding
/// per channel that has them (count, value; more than 1 % of the rows is
/// fatal, as [`super::channels`]' saturation against a recorded range).
pub fn check(name: &str, imu: &Table) -> Vec<Finding> {
    let mut out = Vec::new();
    let n = imu.len();
    for (c, channel) in IMU_COLUMNS.iter().enumerate() {
        let column: Vec<f64> = imu.values.iter().skip(c).step_by(6).copied().collect();
        let Some((count, value)) = clipped(&column, MIN_FULL_SCALE[c / 3]) else {
            continue;
        };
        let share = count as f64 / n as f64;
        let (unit, scale, scale_unit) = if c < 3 {
            ("m/s²", G_STANDARD, "g")
        } else {
            ("rad/s", std::f64::consts::PI / 180.0, "°/s")
        };
        let near = FULL_SCALES[c / 3]
            .iter()
            .find(|fs| ((value.abs() / scale) / **fs - 1.0).abs() < FULL_SCALE_TOLERANCE)
            .map(|fs| format!(", a typical full scale ±{fs} {scale_unit}"))
            .unwrap_or_default();
        let severity = saturation_severity(share);
        out.push(Finding::new(
            "saturation",
            severity,
            *channel,
            count as f64,
            format!(
                "{name}: {channel} saturated: {count} samples ({:.2} %) in runs of ≥ {CLIP_RUN} at \
                 its extreme {value:.4} {unit} ({:.1} {scale_unit}{near})",
                100.0 * share,
                value / scale
            ),
            "choose a larger range, or a slower motion; the clipped samples are wrong (cut those stretches out)",
        ));
    }
    out
}

/// The samples of `v` in runs of at least `CLIP_RUN` identical values at
/// the largest |value| (within [`SATURATION`]), and that value; `None`
/// when there are none or the extreme is below `min_full_scale`.
fn clipped(v: &[f64], min_full_scale: f64) -> Option<(usize, f64)> {
    let max = v.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    if max < SATURATION * min_full_scale {
        return None;
    }
    let (mut count, mut worst, mut i) = (0usize, 0.0f64, 0usize);
    while i < v.len() {
        let mut j = i + 1;
        while j < v.len() && v[j] == v[i] {
            j += 1;
        }
        if j - i >= CLIP_RUN && v[i].abs() >= SATURATION * max {
            count += j - i;
            worst = if v[i].abs() > worst.abs() {
                v[i]
            } else {
                worst
            };
        }
        i = j;
    }
    (count > 0).then_some((count, worst))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::check::Severity;

    /// A table of `n` rows at 100 Hz: a smooth motion, every channel moving.
    fn smooth(n: usize) -> Table {
        let mut values = Vec::with_capacity(6 * n);
        for i in 0..n {
            let s = i as f64 * 0.01;
            values.extend([
                3.0 * s.sin(),
                2.0 * (1.3 * s).cos(),
                9.81 + 0.5 * (0.7 * s).sin(),
                1.5 * (0.9 * s).sin(),
                0.8 * (1.1 * s).cos(),
                0.3 * (0.5 * s).sin(),
            ]);
        }
        Table {
            columns: IMU_COLUMNS.iter().map(|c| c.to_string()).collect(),
            t: (0..n).map(|i| i as f64 * 0.01).collect(),
            values,
        }
    }

    #[test]
    fn a_clipped_gyro_channel_is_counted_and_a_clean_one_is_not() {
        let mut imu = smooth(2000);
        assert!(check("imu.csv", &imu).is_empty());
        // gy clipped at +250 °/s over two stretches of 30 and 20 samples
        let fs = 250f64.to_radians();
        for i in (100..130).chain(900..920) {
            imu.values[6 * i + 4] = fs;
        }
        let f = check("imu.csv", &imu);
        assert_eq!(f.len(), 1, "{f:#?}");
        assert_eq!((f[0].kind, f[0].subject.as_str()), ("saturation", "gy"));
        assert_eq!(f[0].value, 50.0);
        assert_eq!(f[0].severity, Severity::Fatal, "50 of 2000 rows");
        assert!(f[0].message.contains("±250 °/s"), "{}", f[0].message);
    }

    #[test]
    fn an_accelerometer_at_rest_is_not_saturated() {
        let mut imu = smooth(500);
        // az repeats g at rest, its largest value: below 2 g, not clipping
        for i in 0..500 {
            imu.values[6 * i + 2] = if i < 300 { 9.81 } else { 9.0 };
        }
        assert!(check("imu.csv", &imu).is_empty());
        // a short run at the extreme is not clipping; a long one is
        imu.values[6 * 10] = 25.0;
        imu.values[6 * 11] = 25.0;
        assert!(check("imu.csv", &imu).is_empty());
        for i in 12..16 {
            imu.values[6 * i] = 25.0;
        }
        let f = check("imu.csv", &imu);
        assert_eq!(f[0].subject, "ax");
        assert_eq!((f[0].value, f[0].severity), (6.0, Severity::Fatal));
    }
}
