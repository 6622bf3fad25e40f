//! The alias rule (`robimu_protocol::alias`) against a brute-force
//! reference: the age of each read simulated on two clocks, its spectrum
//! taken by a zero-padded FFT, its lines found and compared with the rule.

use robimu_protocol::{
    AliasSensor, SensorConfig, SensorTiming, ALIAS_CLOCK_TOLERANCE, ALIAS_MARGIN_HZ,
    ALIAS_MIN_AMPLITUDE_S, DEFAULT_SAMPLE_RATE_HZ,
};

/// In-place radix-2 FFT (length a power of two).
fn fft(re: &mut [f64], im: &mut [f64]) {
    let n = re.len();
    let mut j = 0;
    for i in 1..n {
        let mut bit = n >> 1;
        while j & bit != 0 {
            j ^= bit;
            bit >>= 1;
        }
        j |= bit;
        if i < j {
            re.swap(i, j);
            im.swap(i, j);
        }
    }
    let mut len = 2;
    while len <= n {
        let ang = -2.0 * std::f64::consts::PI / len as f64;
        for start in (0..n).step_by(len) {
            for k in 0..len / 2 {
                let (s, c) = (ang * k as f64).sin_cos();
                let (a, b) = (start + k, start + k + len / 2);
                let (tr, ti) = (re[b] * c - im[b] * s, re[b] * s + im[b] * c);
                re[b] = re[a] - tr;
                im[b] = im[a] - ti;
                re[a] += tr;
                im[a] += ti;
            }
        }
        len <<= 1;
    }
}

/// The ages of `n` reads at `rate_hz` (board clock, first read at `t0`)
/// of a sensor updating at `odr_hz` on a chip clock (1 + `eps`) fast.
fn ages(rate_hz: f64, odr_hz: f64, eps: f64, t0: f64, n: usize) -> Vec<f64> {
    let period = 1.0 / (odr_hz * (1.0 + eps));
    (0..n)
        .map(|i| {
            let t = t0 + i as f64 / rate_hz;
            t - (t / period).floor() * period
        })
        .collect()
}

/// Spectral lines of `x` sampled at `rate_hz`: (frequency, amplitude) of
/// every local maximum of the Hann-windowed, 4× zero-padded amplitude
/// spectrum above `floor` (amplitude of a sinusoid, the mean removed).
fn lines(x: &[f64], rate_hz: f64, floor: f64) -> Vec<(f64, f64)> {
    let n = x.len();
    let m = 4 * n.next_power_of_two();
    let mean = x.iter().sum::<f64>() / n as f64;
    let w: Vec<f64> = (0..n)
        .map(|i| 0.5 - 0.5 * (2.0 * std::f64::consts::PI * i as f64 / n as f64).cos())
        .collect();
    let gain: f64 = w.iter().sum();
    let mut re = vec![0.0; m];
    let mut im = vec![0.0; m];
    for i in 0..n {
        re[i] = (x[i] - mean) * w[i];
    }
    fft(&mut re, &mut im);
    let amp: Vec<f64> = (0..=m / 2)
        .map(|k| 2.0 * re[k].hypot(im[k]) / gain)
        .collect();
    (1..m / 2)
        .filter(|&k| amp[k] >= floor && amp[k] >= amp[k - 1] && amp[k] > amp[k + 1])
        .map(|k| (k as f64 * rate_hz / m as f64, amp[k]))
        .collect()
}

fn timing(accel_odr_hz: f32, gyro_odr_hz: f32) -> SensorTiming {
    SensorTiming {
        accel_bandwidth_hz: accel_odr_hz / 2.0,
        accel_odr_hz,
        gyro_bandwidth_hz: 116.0,
        gyro_odr_hz,
    }
}

/// For each case (rate, ODR, chip clock error; ratios without a short
/// common period, so that harmonics do not pile up on one line), the
/// lowest-frequency strong
/// line of the simulated age sequence (amplitude above the midpoint between
/// the weakest harmonic that counts and the strongest that does not) is at
/// the rule's lowest [`AliasLine::frequency_hz`] within 0.02 Hz, with the
/// rule's amplitude 1/(πkF) within 3 %; every line the rule lists is in
/// the spectrum; no strong line is missing from the rule.
#[test]
fn the_lowest_strong_line_of_a_simulated_age_sequence_is_the_rules() {
    let cases = [
        (120.0, 125.0, 0.0083),
        (150.0, 125.0, 0.0083),
        (150.0, 125.0, -0.0131),
        (100.0, 125.0, 0.0083),
        (173.0, 125.0, 0.0),
        (230.0, 250.0, 0.0113),
        (150.0, 400.0, 0.0083),
        (100.0, 200.0, -0.0061),
    ];
    for (rate, odr, eps) in cases {
        let t = timing(odr as f32, 1000.0);
        let rule: Vec<_> = t
            .alias_lines(rate, eps)
            .filter(|l| l.sensor == AliasSensor::Accel)
            .collect();
        let k_max = rule.len() as f64;
        assert!(k_max >= 1.0, "{rate} Hz, {odr} Hz: no line");
        let weakest = 1.0 / (std::f64::consts::PI * k_max * odr);
        let strongest_out = 1.0 / (std::f64::consts::PI * (k_max + 1.0) * odr);
        assert!(strongest_out < ALIAS_MIN_AMPLITUDE_S && weakest >= ALIAS_MIN_AMPLITUDE_S);
        let threshold = 0.5 * (weakest + strongest_out);
        let x = ages(rate, odr, eps, 0.123_4e-3, 1 << 14);
        let found = lines(&x, rate, 0.2 * threshold);
        let strong: Vec<(f64, f64)> = found.iter().copied().filter(|l| l.1 >= threshold).collect();
        let lowest = strong.iter().map(|l| l.0).fold(f64::INFINITY, f64::min);
        let want = rule
            .iter()
            .map(|l| l.frequency_hz)
            .fold(f64::INFINITY, f64::min);
        assert!(
            (lowest - want).abs() < 0.02,
            "{rate} Hz, {odr} Hz, ε {eps}: lowest strong line {lowest} Hz, rule {want} Hz; {strong:?}"
        );
        for l in &rule {
            let near = found
                .iter()
                .filter(|s| (s.0 - l.frequency_hz).abs() < 0.02)
                .map(|s| s.1)
                .fold(0.0, f64::max);
            // lines of several harmonics at one frequency add: only a
            // lone line's amplitude is compared
            let alone = rule
                .iter()
                .filter(|o| (o.frequency_hz - l.frequency_hz).abs() < 0.05)
                .count()
                == 1;
            if alone && l.frequency_hz > 0.5 && l.frequency_hz < rate / 2.0 - 0.5 {
                assert!(
                    (near / l.amplitude_s - 1.0).abs() < 0.03,
                    "{rate} Hz, {odr} Hz, ε {eps}, k {}: amplitude {near} vs {}",
                    l.harmonic,
                    l.amplitude_s
                );
            }
        }
        for s in &strong {
            assert!(
                rule.iter().any(|l| (l.frequency_hz - s.0).abs() < 0.02),
                "{rate} Hz, {odr} Hz, ε {eps}: strong line {s:?} not in the rule {rule:?}"
            );
        }
    }
}

/// The margin is the lowest frequency a counted line reaches for any chip
/// clock within ±δ (clipped at 0): brute force over 801 clock errors
/// against the closed form f·‖kF/f‖ − kFδ, for every rate 100…400 Hz.
#[test]
fn the_margin_is_the_lowest_line_over_the_clock_tolerance() {
    let t = SensorTiming::of(&SensorConfig::default());
    for rate in 100..=400u16 {
        let f = f64::from(rate);
        let steps = 800;
        let brute = (0..=steps)
            .map(|i| ALIAS_CLOCK_TOLERANCE * (2.0 * i as f64 / steps as f64 - 1.0))
            .flat_map(|eps| t.alias_lines(f, eps).map(|l| l.frequency_hz))
            .fold(f64::INFINITY, f64::min);
        let margin = t.alias_margin_hz(f);
        // the ε grid's step moves a line by at most kF·2δ/800 (k ≤ 4, F = 125)
        let resolution = 4.0 * 125.0 * 2.0 * ALIAS_CLOCK_TOLERANCE / steps as f64;
        assert!(
            (brute - margin.max(0.0)).abs() <= resolution + 1e-9,
            "{rate} Hz: brute force {brute}, margin {margin}"
        );
    }
}

/// The default bandwidths: 125 Hz accelerometer (k = 1…4 count, amplitudes
/// 2.5 … 0.64 ms), 1000 Hz gyroscope (0.32 ms: none). By hand: 120 Hz has
/// the fundamental at 125 − 120 = 5 Hz, margin 5 − 2.5 = 2.5 Hz; 100 Hz
/// the 4th harmonic at 500 = 5·100 Hz, 0 Hz, margin −4·125·0.02 = −10 Hz;
/// 150 Hz the fundamental at 150 − 125 = 25 Hz, margin 22.5 Hz, and the
/// other harmonics 50, 75, 50 Hz less 5, 7.5, 10 Hz. 110…140 Hz fail (the
/// fundamental at 15 … 15 Hz less 2.5 Hz, or the 4th harmonic), so 150 Hz
/// is the default, and SensorConfig::default() reads at it.
#[test]
fn the_default_rate_is_the_rules_choice_for_the_default_bandwidths() {
    let config = SensorConfig::default();
    let t = SensorTiming::of(&config);
    assert_eq!(t.alias_lines(150.0, 0.0).count(), 4);
    assert!(t
        .alias_lines(150.0, 0.0)
        .all(|l| l.sensor == AliasSensor::Accel));
    let close = |a: f64, b: f64| (a - b).abs() < 1e-9;
    assert!(close(t.alias_margin_hz(120.0), 2.5));
    assert!(close(t.alias_margin_hz(100.0), -10.0));
    assert!(close(t.alias_margin_hz(150.0), 22.5));
    let worst = t.worst_alias(150.0).unwrap();
    assert_eq!(worst.harmonic, 1);
    assert!(close(worst.frequency_hz, 25.0));
    for rate in (100..150).step_by(10) {
        assert!(!t.rate_choice(rate).alias_free, "{rate} Hz");
    }
    let choice = t.alias_free_rate();
    assert!(choice.alias_free && choice.margin_hz >= ALIAS_MARGIN_HZ);
    assert_eq!(choice.rate_hz, DEFAULT_SAMPLE_RATE_HZ);
    assert_eq!(config.sample_rate_hz, DEFAULT_SAMPLE_RATE_HZ);
    assert_eq!(t.nearest_alias_free_rate(120), Some(150));
    assert_eq!(t.nearest_alias_free_rate(150), Some(150));
}

/// Timings from the wire that make no sense (NaN, zero or negative ODRs)
/// give no line and an infinite margin, without panicking; a gyroscope at
/// 400 Hz (47 Hz bandwidth, 0.8 ms fundamental) counts.
#[test]
fn odd_timings_give_no_lines_and_slow_gyroscopes_count() {
    for odr in [f32::NAN, 0.0, -125.0, f32::INFINITY] {
        let t = timing(odr, odr);
        assert_eq!(t.alias_lines(150.0, 0.0).count(), 0);
        assert_eq!(t.alias_margin_hz(150.0), f64::INFINITY);
        assert!(t.alias_free_rate().alias_free);
    }
    let t = timing(125.0, 1000.0);
    assert_eq!(t.alias_lines(f64::NAN, 0.0).count(), 0);
    let t = timing(2000.0, 400.0);
    let lines: Vec<_> = t.alias_lines(150.0, 0.0).collect();
    assert_eq!(lines.len(), 1);
    assert_eq!(lines[0].sensor, AliasSensor::Gyro);
    // 400/150 = 2.667: 50 Hz, less 400·0.02 = 8 Hz
    assert!((lines[0].margin_hz - 42.0).abs() < 1e-9);
}
