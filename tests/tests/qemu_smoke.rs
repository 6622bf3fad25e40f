//! QEMU smoke test (issue "Acquisition foundation" §4): the acquisition core,
//! cross-compiled for thumbv7em-none-eabihf with a simulated BNO055 on its
//! I²C bus, boots on QEMU's `mps2-an386` (Cortex-M4F) and streams frames on
//! UART0, captured to a file and decoded here with the host decoder.
//!
//! Needs `qemu-system-arm` (Debian package `qemu-system-arm`) and the
//! `thumbv7em-none-eabihf` Rust target, hence ignored by default:
//! `cargo test -p robimu-tests --test qemu_smoke -- --ignored`.

use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use robimu_bno055_sim::SineSource;
use robimu_protocol::{DeviceDecoder, DeviceInfo, DeviceMessage, ImuSample, Status};

/// Consecutive samples required by the issue.
const MIN_SAMPLES: usize = 100;
/// QEMU's wall-time budget; the image exits by itself long before.
const QEMU_TIMEOUT: Duration = Duration::from_secs(180);
/// Virtual time per guest instruction, 2^shift ns: makes the guest's clock a
/// pure function of the instructions executed (deterministic, immune to host
/// load) while running at a usable speed. Must match `qemu-mps2/run.sh`.
const ICOUNT_SHIFT: &str = "shift=6,sleep=off";
/// Sensor readings latched per streamed sample at most (sample burst plus
/// the occasional temperature read, with margin).
const MAX_LATCHES_PER_SAMPLE: u64 = 4;
const TARGET: &str = "thumbv7em-none-eabihf";

fn boards_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../firmware/boards")
}

/// Fails with the install hint when `qemu-system-arm` cannot run.
fn require_qemu() {
    let out = Command::new("qemu-system-arm").arg("--version").output();
    match out {
        Ok(o) if o.status.success() => {}
        Ok(o) => panic!("qemu-system-arm --version failed: {o:?}"),
        Err(e) => panic!(
            "qemu-system-arm not runnable ({e}); install Debian's package: \
             apt-get install qemu-system-arm"
        ),
    }
}

/// Fails with the install hint when the Rust target's standard library is missing.
fn require_target(cargo: &str) {
    let rustc = std::env::var("RUSTC").unwrap_or_else(|_| "rustc".into());
    // `rustc` resolves the toolchain the boards workspace will use.
    let sysroot = Command::new(&rustc)
        .current_dir(boards_dir())
        .args(["--print", "sysroot"])
        .output()
        .unwrap_or_else(|e| panic!("cannot run {rustc} (next to {cargo}): {e}"));
    let sysroot = String::from_utf8_lossy(&sysroot.stdout).trim().to_string();
    let lib = Path::new(&sysroot).join("lib/rustlib").join(TARGET);
    assert!(
        lib.is_dir(),
        "the Rust target {TARGET} is not installed in {sysroot}: rustup target add {TARGET}"
    );
}

/// `cargo build --release -p robimu-qemu-mps2` in the boards workspace; the ELF.
fn build_image(cargo: &str) -> PathBuf {
    let boards = boards_dir();
    let target_dir = boards.join("target");
    let status = Command::new(cargo)
        .current_dir(&boards)
        .args(["build", "--release", "-p", "robimu-qemu-mps2"])
        .env("CARGO_TARGET_DIR", &target_dir)
        // The outer `cargo test` may carry host-only settings.
        .env_remove("RUSTFLAGS")
        .env_remove("CARGO_ENCODED_RUSTFLAGS")
        .env_remove("CARGO_BUILD_TARGET")
        .env_remove("CARGO_BUILD_RUSTFLAGS")
        .status()
        .unwrap_or_else(|e| panic!("cannot run {cargo}: {e}"));
    assert!(
        status.success(),
        "building the QEMU image failed ({status}): see cargo's output above"
    );
    let elf = target_dir.join(TARGET).join("release/robimu-qemu-mps2");
    assert!(elf.is_file(), "no image at {}", elf.display());
    elf
}

/// Runs the image until it exits by semihosting (or the timeout kills it);
/// returns the bytes it wrote to UART0.
fn run_qemu(elf: &Path) -> Vec<u8> {
    let capture = elf.with_file_name("qemu-smoke-uart0.capture");
    let _ = std::fs::remove_file(&capture);
    let args = [
        "-M".to_string(),
        "mps2-an386".into(),
        "-display".into(),
        "none".into(),
        "-monitor".into(),
        "none".into(),
        "-icount".into(),
        ICOUNT_SHIFT.into(),
        "-semihosting-config".into(),
        "enable=on,target=native".into(),
        "-serial".into(),
        format!("file:{}", capture.display()),
        "-kernel".into(),
        elf.display().to_string(),
    ];
    eprintln!("qemu-system-arm {}", args.join(" "));
    let started = Instant::now();
    let mut child = Command::new("qemu-system-arm")
        .args(&args)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap_or_else(|e| panic!("cannot start qemu-system-arm: {e}"));
    let status = loop {
        if let Some(status) = child.try_wait().expect("waiting for qemu") {
            break status;
        }
        if started.elapsed() > QEMU_TIMEOUT {
            let _ = child.kill();
            let _ = child.wait();
            let got = std::fs::read(&capture).map(|b| b.len()).unwrap_or(0);
            panic!(
                "qemu did not exit within {QEMU_TIMEOUT:?} (killed); UART0 had {got} bytes in {}",
                capture.display()
            );
        }
        std::thread::sleep(Duration::from_millis(50));
    };
    let mut out = String::new();
    let mut err = String::new();
    let _ = child.stdout.take().map(|mut s| s.read_to_string(&mut out));
    let _ = child.stderr.take().map(|mut s| s.read_to_string(&mut err));
    eprintln!(
        "qemu exited with {status} after {:.1} s; guest semihosting output:\n{out}{err}",
        started.elapsed().as_secs_f64()
    );
    assert!(
        status.success(),
        "the image failed (semihosting exit status {status}): {out}{err}"
    );
    std::fs::read(&capture)
        .unwrap_or_else(|e| panic!("no UART capture at {}: {e}", capture.display()))
}

#[test]
#[ignore = "needs qemu-system-arm and the thumbv7em target; run by .ci/run"]
fn qemu_image_boots_and_streams_gapless_samples() {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    require_qemu();
    require_target(&cargo);
    let elf = build_image(&cargo);
    let bytes = run_qemu(&elf);

    let mut decoder = DeviceDecoder::new();
    let mut messages = Vec::new();
    for result in decoder.feed(&bytes) {
        match result {
            Ok(m) => messages.push(m),
            Err(e) => panic!("decode error after {} frames: {e}", messages.len()),
        }
    }
    let stats = *decoder.stats();
    assert_eq!(stats.errors(), 0, "decoder rejected frames: {stats:?}");
    assert_eq!(
        decoder.pending_len(),
        0,
        "the capture ends inside a frame ({} bytes pending)",
        decoder.pending_len()
    );

    // A DeviceInfo per sensor first, from the two simulated BNO055 (protocol 3).
    let infos: Vec<DeviceInfo> = messages
        .iter()
        .take(2)
        .map(|m| match m {
            DeviceMessage::Info(info) => *info,
            other => panic!("the first two frames are not DeviceInfo: {other:?}"),
        })
        .collect();
    for (k, info) in infos.iter().enumerate() {
        assert_eq!((info.sensor as usize, info.sensors), (k, 2), "{info:?}");
        assert_eq!(info.chip_id, 0xA0, "BNO055 CHIP_ID");
        assert_eq!(info.accel_id, 0xFB, "ACC_ID");
        assert_eq!(info.mag_id, 0x32, "MAG_ID");
        assert_eq!(info.gyro_id, 0x0F, "GYR_ID");
        assert_eq!(info.protocol_version, robimu_protocol::PROTOCOL_VERSION);
    }
    let info = infos[0];
    let rate_hz = f64::from(info.config.sample_rate_hz);
    assert!(rate_hz > 0.0, "configured rate {rate_hz}");

    let all: Vec<ImuSample> = messages
        .iter()
        .filter_map(|m| match m {
            DeviceMessage::Sample(s) => Some(*s),
            _ => None,
        })
        .collect();
    let statuses: Vec<Status> = messages
        .iter()
        .filter_map(|m| match m {
            DeviceMessage::Status(s) => Some(*s),
            _ => None,
        })
        .collect();
    let others = messages.len() - 2 - all.len() - statuses.len();
    assert_eq!(others, 0, "unexpected frames: {messages:?}");
    let period_us = 1e6 / rate_hz;
    let mut summary = Vec::new();
    // Each sensor's stream: the image's SineSource (period 200 for sensor 0,
    // SECOND_SINE_PERIOD = 150 for sensor 1).
    for (k, sine_period) in [(0u8, 200u32), (1, 150)] {
        let samples: Vec<ImuSample> = all.iter().filter(|s| s.sensor == k).copied().collect();
        assert!(
            samples.len() >= MIN_SAMPLES,
            "sensor {k}: {} samples, want at least {MIN_SAMPLES}",
            samples.len()
        );

        // No sequence gap, strictly increasing device time at the configured rate.
        for pair in samples.windows(2) {
            let (a, b) = (pair[0], pair[1]);
            assert_eq!(b.seq, a.seq.wrapping_add(1), "seq gap: {a:?} then {b:?}");
            let dt = b.t_us.wrapping_sub(a.t_us);
            assert!(
                dt > 0 && f64::from(dt) > 0.5 * period_us && f64::from(dt) < 1.5 * period_us,
                "sample interval {dt} µs, configured period {period_us:.1} µs: {a:?} then {b:?}"
            );
        }
        let (first, last) = (samples[0], samples[samples.len() - 1]);
        let span = f64::from(last.t_us.wrapping_sub(first.t_us));
        let mean = span / (samples.len() - 1) as f64;
        assert!(
            (mean - period_us).abs() < 0.01 * period_us,
            "mean sample interval {mean:.1} µs, configured {period_us:.1} µs"
        );
        // The simulated sensor lies flat: gravity (981 counts = 9.81 m/s²) on +z.
        for s in &samples {
            let z = f64::from(s.accel_raw[2]) * f64::from(info.accel_scale_mps2_per_lsb);
            assert!((z - 9.81).abs() < 1.0, "accel z {z} m/s² in {s:?}");
        }
        // Bit-exact payloads: each sample is the image's sine source's
        // reading number n, recomputed here, with n increasing. The sensor latches
        // a new reading per burst read of its data registers, and the core also
        // reads the temperature register now and then, so n may skip a few.
        let reference = SineSource::new(sine_period);
        let mut next_n = 0u64;
        for (i, s) in samples.iter().enumerate() {
            let n = (next_n..next_n + MAX_LATCHES_PER_SAMPLE)
                .find(|&n| {
                    let r = reference.reading(n);
                    r.accel == s.accel_raw && r.gyro == s.gyro_raw
                })
                .unwrap_or_else(|| {
                    panic!(
                        "sensor {k} sample {i} {s:?} is none of the simulated readings {next_n}..{}",
                        next_n + MAX_LATCHES_PER_SAMPLE
                    )
                });
            assert_eq!(
                s.temp_raw,
                reference.reading(n).temp,
                "temperature of sample {i}"
            );
            next_n = n + 1;
        }
        summary.push(format!(
            "sensor {k}: {} samples (seq {}..={}), mean interval {mean:.1} µs, {next_n} readings latched",
            samples.len(),
            first.seq,
            last.seq
        ));
    }
    // Health reports, if any, saw nothing lost.
    for st in &statuses {
        assert_eq!(st.samples_dropped, 0, "{st:?}");
        assert_eq!(st.i2c_errors, 0, "{st:?}");
    }
    eprintln!(
        "qemu smoke: 2 DeviceInfo + {} status frames, {} bytes at {rate_hz} Hz; {}",
        statuses.len(),
        bytes.len(),
        summary.join("; ")
    );
}
