//! Datasheet mode against the datasheet's tables (update rate per
//! bandwidth setting, stale reads between updates), against the filter's
//! analytic group delay and −3 dB point, and register-driven reconfiguration.

use embedded_hal::i2c::I2c;

use super::*;
use crate::Stimulus;

const ADDR: u8 = 0x28;

/// Input as a function of time: (accelerometer m/s², gyroscope rad/s).
type Signal = fn(f64) -> ([f64; 3], [f64; 3]);

/// A stimulus every `dt` seconds from t = 0.
struct Clocked {
    t: f64,
    dt: f64,
    f: Signal,
    temp_c: f64,
}

impl SampleSource for Clocked {
    fn sample(&mut self) -> RawReading {
        RawReading::default()
    }

    fn stimulus(&mut self) -> Option<Stimulus> {
        let t = self.t;
        self.t += self.dt;
        let (accel_mps2, gyro_rads) = (self.f)(t);
        Some(Stimulus {
            t_s: t,
            accel_mps2,
            gyro_rads,
            temp_c: self.temp_c,
        })
    }
}

fn chip(dt: f64, f: Signal) -> Bno055Sim<Clocked> {
    Bno055Sim::new(
        ADDR,
        Clocked {
            // off the internal ticks, so no read lands on one
            t: 1.3e-5,
            dt,
            f,
            temp_c: 25.0,
        },
    )
    .with_model(ChipModel::Datasheet)
}

fn write(sim: &mut Bno055Sim<Clocked>, reg: u8, value: u8) {
    sim.write(ADDR, &[reg, value]).unwrap();
}

/// CONFIG mode, the two config registers and `UNIT_SEL`, then AMG mode.
fn configure(sim: &mut Bno055Sim<Clocked>, acc_config: u8, gyr_config_0: u8, unit_sel: u8) {
    write(sim, OPR_MODE, MODE_CONFIG);
    write(sim, PAGE_ID, 1);
    write(sim, ACC_CONFIG, acc_config);
    write(sim, GYR_CONFIG_0, gyr_config_0);
    write(sim, PAGE_ID, 0);
    write(sim, UNIT_SEL, unit_sel);
    write(sim, OPR_MODE, MODE_AMG);
}

/// (time of the stimulus a read ran to, accelerometer, gyroscope counts).
type Read = (f64, [i16; 3], [i16; 3]);

/// One 18-byte AMG burst as the firmware reads it (one stimulus).
fn read(sim: &mut Bno055Sim<Clocked>) -> Read {
    let t = sim.source_mut().t;
    let mut buf = [0u8; 18];
    sim.write_read(ADDR, &[ACC_DATA], &mut buf).unwrap();
    let v = |at: usize| -> [i16; 3] {
        core::array::from_fn(|i| i16::from_le_bytes([buf[at + 2 * i], buf[at + 2 * i + 1]]))
    };
    (t, v(0), v(12))
}

/// Datasheet tables 3-8 / 3-9 (BMA280 ODR = 2 × bandwidth; BMG160 rates),
/// written out independently of `timing`: (bandwidth, ODR) per code 0..7.
const ACCEL_TABLE: [(f64, f64); 8] = [
    (7.8125, 15.625),
    (15.625, 31.25),
    (31.25, 62.5),
    (62.5, 125.0),
    (125.0, 250.0),
    (250.0, 500.0),
    (500.0, 1000.0),
    (1000.0, 2000.0),
];
const GYRO_TABLE: [(f64, f64); 8] = [
    (523.0, 2000.0),
    (230.0, 2000.0),
    (116.0, 1000.0),
    (47.0, 400.0),
    (23.0, 200.0),
    (12.0, 100.0),
    (64.0, 200.0),
    (32.0, 100.0),
];

/// Ramps: 100 m/s² per s (±16 g range), 20 rad/s per s (±2000 °/s).
const ACCEL_SLOPE: f64 = 100.0;
const GYRO_SLOPE: f64 = 20.0;
fn ramps(t: f64) -> ([f64; 3], [f64; 3]) {
    (
        [ACCEL_SLOPE * t, -ACCEL_SLOPE * t, 0.5 * ACCEL_SLOPE * t],
        [GYRO_SLOPE * t, -GYRO_SLOPE * t, 0.5 * GYRO_SLOPE * t],
    )
}

/// Whether an internal tick k/odr lies in (a, b].
fn tick_between(a: f64, b: f64, odr: f64) -> bool {
    libm::floor(b * odr) > libm::floor(a * odr)
}

#[test]
fn each_bandwidth_setting_updates_at_its_datasheet_rate_and_holds_between() {
    for code in 0..8u8 {
        // 20 kHz reads for 1 s; ±16 g, m/s² and rad/s units.
        let mut sim = chip(5e-5, ramps);
        configure(&mut sim, (code << 2) | 0x03, code << 3, 0x02);
        let (acc_bw, acc_odr) = ACCEL_TABLE[usize::from(code)];
        let (gyr_bw, gyr_odr) = GYRO_TABLE[usize::from(code)];
        assert_eq!(sim.timing(Sensor::Accel).bandwidth_hz, acc_bw);
        assert_eq!(sim.timing(Sensor::Gyro).bandwidth_hz, gyr_bw);
        let (mut t_prev, mut acc_prev, mut gyr_prev) = read(&mut sim);
        let (mut acc_changes, mut gyr_changes) = (0u32, 0u32);
        while sim.source_mut().t < 1.0 {
            let (t, acc, gyr) = read(&mut sim);
            // a read returns a new value exactly when an internal tick
            // passed since the last read, else the previous one (stale)
            assert_eq!(
                acc != acc_prev,
                tick_between(t_prev, t, acc_odr),
                "accel code {code} t={t}"
            );
            assert_eq!(
                gyr != gyr_prev,
                tick_between(t_prev, t, gyr_odr),
                "gyro code {code} t={t}"
            );
            acc_changes += u32::from(acc != acc_prev);
            gyr_changes += u32::from(gyr != gyr_prev);
            (t_prev, acc_prev, gyr_prev) = (t, acc, gyr);
        }
        assert!(
            (f64::from(acc_changes) - acc_odr).abs() <= 1.0,
            "code {code}: {acc_changes}"
        );
        assert!(
            (f64::from(gyr_changes) - gyr_odr).abs() <= 1.0,
            "code {code}: {gyr_changes}"
        );
        assert_eq!(u64::from(acc_changes), sim.updates(Sensor::Accel));
    }
}

/// A chip clock off by ε: the registers change exactly when an update
/// instant k/(ODR·(1 + ε)) passed since the last read (independent of the
/// pipeline's bookkeeping), so over 2 s a sensor updates 2·ODR·(1 + ε)
/// times (±1): +0.8 % and −1.5 % at the defaults (125 Hz: 252 and 246;
/// 1000 Hz: 2016 and 1970, against 250 and 2000 without the error).
#[test]
fn a_chip_clock_error_scales_the_update_instants() {
    for ppm in [8_000.0, -15_000.0] {
        let eps: f64 = ppm * 1e-6;
        let mut sim = chip(5e-5, ramps).with_clock_error_ppm(ppm);
        assert_eq!(sim.clock_error_ppm(), ppm);
        // ±16 g, 62.5 Hz; 116 Hz gyroscope; m/s² and rad/s units
        configure(&mut sim, (3 << 2) | 0x03, 2 << 3, 0x02);
        let (acc_odr, gyr_odr) = (
            ACCEL_TABLE[3].1 * (1.0 + eps),
            GYRO_TABLE[2].1 * (1.0 + eps),
        );
        let (mut t_prev, mut acc_prev, mut gyr_prev) = read(&mut sim);
        let (mut acc_changes, mut gyr_changes) = (0u32, 0u32);
        while sim.source_mut().t < 2.0 {
            let (t, acc, gyr) = read(&mut sim);
            assert_eq!(
                acc != acc_prev,
                tick_between(t_prev, t, acc_odr),
                "accel ε {eps} t={t}"
            );
            assert_eq!(
                gyr != gyr_prev,
                tick_between(t_prev, t, gyr_odr),
                "gyro ε {eps} t={t}"
            );
            acc_changes += u32::from(acc != acc_prev);
            gyr_changes += u32::from(gyr != gyr_prev);
            (t_prev, acc_prev, gyr_prev) = (t, acc, gyr);
        }
        assert!(
            (f64::from(acc_changes) - 2.0 * acc_odr).abs() <= 1.0,
            "ε {eps}: {acc_changes}"
        );
        assert!(
            (f64::from(gyr_changes) - 2.0 * gyr_odr).abs() <= 1.0,
            "ε {eps}: {gyr_changes}"
        );
    }
    // bad values are no clock error
    assert_eq!(
        chip(1e-3, ramps)
            .with_clock_error_ppm(f64::NAN)
            .clock_error_ppm(),
        0.0
    );
}

#[test]
fn a_ramp_lags_by_the_filters_analytic_group_delay() {
    // Two first-order sections of time constant T = √(√2−1)/(2π f_bw):
    // a ramp's lag is 2T, written out here from the bandwidth alone.
    let delay = |bw: f64| 2.0 * (2f64.sqrt() - 1.0).sqrt() / (2.0 * core::f64::consts::PI * bw);
    for code in 0..8u8 {
        let mut sim = chip(5e-5, ramps);
        configure(&mut sim, (code << 2) | 0x03, code << 3, 0x02);
        let (acc_bw, acc_odr) = ACCEL_TABLE[usize::from(code)];
        let (gyr_bw, gyr_odr) = GYRO_TABLE[usize::from(code)];
        let (mut t_prev, mut acc_prev, mut gyr_prev) = read(&mut sim);
        let mut checked = 0;
        while sim.source_mut().t < 1.0 {
            let (t, acc, gyr) = read(&mut sim);
            // settled after 0.5 s (> 30 T at the lowest bandwidth)
            if t > 0.5 {
                for (new, old, odr, bw, per_unit, slope) in [
                    (acc[0], acc_prev[0], acc_odr, acc_bw, 100.0, ACCEL_SLOPE),
                    (gyr[0], gyr_prev[0], gyr_odr, gyr_bw, 900.0, GYRO_SLOPE),
                ] {
                    if new != old {
                        let tick = libm::floor(t * odr) / odr;
                        let lag = tick - f64::from(new) / per_unit / slope;
                        let tol = 0.5 / per_unit / slope + 1e-9;
                        assert!(
                            (lag - delay(bw)).abs() <= tol,
                            "code {code} bw {bw}: lag {lag} vs {}",
                            delay(bw)
                        );
                        checked += 1;
                    }
                }
            }
            (t_prev, acc_prev, gyr_prev) = (t, acc, gyr);
        }
        let _ = t_prev;
        assert!(
            checked as f64 > 0.49 * (acc_odr + gyr_odr),
            "code {code}: {checked}"
        );
    }
}

#[test]
fn a_sine_at_the_bandwidth_comes_out_3_db_down() {
    // gyroscope 12 Hz (ODR 100 Hz): 25 distinct phases every 3 periods, so
    // the largest update is within cos(π/25) of the amplitude
    fn sine(t: f64) -> ([f64; 3], [f64; 3]) {
        let s = 10.0 * (2.0 * core::f64::consts::PI * 12.0 * t).sin();
        ([0.0; 3], [s, 0.0, 0.0])
    }
    let mut sim = chip(1e-4, sine);
    configure(&mut sim, 0x0D, 5 << 3, 0x02);
    let mut peak = 0i16;
    while sim.source_mut().t < 3.0 {
        let (t, _, gyr) = read(&mut sim);
        if t > 1.0 {
            peak = peak.max(gyr[0].abs());
        }
    }
    let expected = 10.0 / 2f64.sqrt() * 900.0;
    let peak = f64::from(peak);
    assert!(
        peak <= expected + 1.0 && peak >= expected * (core::f64::consts::PI / 25.0).cos() - 1.0,
        "{peak} vs {expected}"
    );
}

#[test]
fn reads_between_updates_return_the_previous_value_at_power_on_defaults() {
    // Power-on defaults (62.5 Hz → 125 Hz, 32 Hz → 100 Hz; m/s², °/s),
    // read at 1 kHz: each accelerometer value is read 8 times, each
    // gyroscope value 10 times.
    let mut sim = chip(1e-3, ramps);
    write(&mut sim, OPR_MODE, MODE_AMG);
    assert_eq!(sim.timing(Sensor::Accel).odr_hz, 125.0);
    assert_eq!(sim.timing(Sensor::Gyro).odr_hz, 100.0);
    // 0.3 s: the ramps stay within ±4 g and ±2000 °/s
    let reads: std::vec::Vec<_> = (0..300).map(|_| read(&mut sim)).collect();
    let runs = |pick: fn(&Read) -> i16| {
        let mut runs = std::vec::Vec::new();
        let mut n = 1;
        for w in reads.windows(2) {
            if pick(&w[1]) == pick(&w[0]) {
                n += 1;
            } else {
                runs.push(n);
                n = 1;
            }
        }
        runs
    };
    let acc = runs(|r| r.1[0]);
    let gyr = runs(|r| r.2[0]);
    // the first run is cut by the start; the rest are exact
    assert!(acc[1..].iter().all(|&n| n == 8), "{acc:?}");
    assert!(gyr[1..].iter().all(|&n| n == 10), "{gyr:?}");
    assert!(
        acc.len() >= 36 && gyr.len() >= 28,
        "{} {}",
        acc.len(),
        gyr.len()
    );
}

#[test]
fn range_unit_and_bandwidth_registers_drive_the_output() {
    fn strong(_: f64) -> ([f64; 3], [f64; 3]) {
        ([30.0, -30.0, 1.0], [10.0, -1.0, 0.5])
    }
    let mut sim = chip(1e-3, strong);
    // ±2 g, 250 Hz (ODR 500 Hz); ±250 °/s, 47 Hz (ODR 400 Hz); m/s², rad/s
    configure(&mut sim, 5 << 2, (3 << 3) | 0x03, 0x02);
    for _ in 0..200 {
        read(&mut sim);
    }
    let (_, acc, gyr) = read(&mut sim);
    // saturated at 2 g = 19.6133 m/s² (1961 counts), 250 °/s = 4.3633 rad/s (3926)
    assert_eq!(acc, [1961, -1961, 100]);
    assert_eq!(gyr, [3926, -900, 450]);
    // configuration writes are ignored outside CONFIG mode
    write(&mut sim, PAGE_ID, 1);
    write(&mut sim, ACC_CONFIG, 0x0D);
    write(&mut sim, PAGE_ID, 0);
    assert_eq!(sim.timing(Sensor::Accel).odr_hz, 500.0);
    // mg and °/s units, ±16 g: 30 m/s² = 3059 mg; 10 rad/s beyond 250 °/s
    configure(&mut sim, (5 << 2) | 0x03, (3 << 3) | 0x03, 0x01);
    for _ in 0..200 {
        read(&mut sim);
    }
    let (_, acc, gyr) = read(&mut sim);
    assert_eq!(acc, [3059, -3059, 102]);
    assert_eq!(gyr, [4000, -917, 458]);
    // the update rate follows: 500 Hz for 0.2 s is 100 updates
    assert!((sim.updates(Sensor::Accel) as f64 - 100.0).abs() <= 1.0);
    // CONFIG mode zeroes the data and stops the sensors
    write(&mut sim, OPR_MODE, MODE_CONFIG);
    assert_eq!(sim.updates(Sensor::Accel), 0);
    let (_, acc, _) = read(&mut sim);
    assert_eq!(acc, [0; 3]);
}

#[test]
fn the_temperature_register_follows_the_stimulus_in_its_unit() {
    let mut sim = chip(1e-3, ramps);
    write(&mut sim, OPR_MODE, MODE_AMG);
    read(&mut sim);
    assert_eq!(sim.register(0, TEMP), 25);
    configure(&mut sim, 0x0D, 0x38, 0x10); // °F at 2 LSB: 77 °F
    read(&mut sim);
    assert_eq!(sim.register(0, TEMP) as i8, 127); // 154 saturates the signed byte
    sim.source_mut().temp_c = -10.0; // 14 °F = 28
    read(&mut sim);
    assert_eq!(sim.register(0, TEMP), 28);
}

#[test]
fn a_source_without_stimuli_is_served_as_by_the_ideal_chip() {
    let reading = RawReading {
        accel: [1, 2, 3],
        gyro: [4, 5, 6],
        mag: [0; 3],
        temp: 30,
    };
    let mut sim =
        Bno055Sim::new(ADDR, crate::ConstantSource(reading)).with_model(ChipModel::Datasheet);
    sim.write(ADDR, &[OPR_MODE, MODE_AMG]).unwrap();
    let mut buf = [0u8; 2];
    sim.write_read(ADDR, &[GYR_DATA + 4], &mut buf).unwrap();
    assert_eq!(i16::from_le_bytes(buf), 6);
    assert_eq!(sim.samples_latched(), 1);
}
