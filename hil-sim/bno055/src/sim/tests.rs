//! The simulator against datasheet facts, and against the `bno055` driver.

use embedded_hal::i2c::{Error as _, ErrorKind, I2c, NoAcknowledgeSource};

use super::*;
use crate::ConstantSource;

const ADDR: u8 = 0x28;

fn reading() -> RawReading {
    RawReading {
        accel: [-981, 2, 12345],
        gyro: [900, -900, -32768],
        mag: [16, 32, -48],
        temp: -7,
    }
}

fn sim() -> Bno055Sim<ConstantSource> {
    Bno055Sim::new(ADDR, ConstantSource(reading()))
}

fn read(sim: &mut Bno055Sim<ConstantSource>, reg: u8, n: usize) -> std::vec::Vec<u8> {
    let mut buf = std::vec![0u8; n];
    sim.write_read(ADDR, &[reg], &mut buf).unwrap();
    buf
}

fn write(sim: &mut Bno055Sim<ConstantSource>, reg: u8, value: u8) {
    sim.write(ADDR, &[reg, value]).unwrap();
}

fn le(v: i16) -> [u8; 2] {
    v.to_le_bytes()
}

#[test]
fn identity_registers_match_the_datasheet() {
    let mut sim = sim();
    // CHIP_ID, ACC_ID, MAG_ID, GYR_ID, SW_REV_ID_LSB/MSB, BL_REV_ID, PAGE_ID.
    assert_eq!(
        read(&mut sim, 0x00, 8),
        [0xA0, 0xFB, 0x32, 0x0F, 0x11, 0x03, 0x15, 0x00]
    );
    // Reset values of the configuration registers (table 4-2).
    assert_eq!(read(&mut sim, 0x3B, 1), [0x80]); // UNIT_SEL
    assert_eq!(read(&mut sim, 0x3D, 1), [0x00]); // OPR_MODE: CONFIG
    write(&mut sim, 0x07, 1);
    // ACC_Config, MAG_Config, GYR_Config_0, GYR_Config_1
    assert_eq!(read(&mut sim, 0x08, 4), [0x0D, 0x6D, 0x38, 0x00]);
    assert_eq!(read(&mut sim, 0x07, 1), [0x01]);
}

#[test]
fn wrong_address_is_not_acknowledged() {
    let mut sim = sim();
    let mut buf = [0u8; 1];
    let err = sim.write_read(0x29, &[0x00], &mut buf).unwrap_err();
    assert_eq!(
        err.kind(),
        ErrorKind::NoAcknowledge(NoAcknowledgeSource::Address)
    );
    assert_eq!(sim.transaction_count(), 0);
}

#[test]
fn pages_are_selected_by_page_id() {
    let mut sim = sim();
    assert_eq!(read(&mut sim, 0x08, 1), [0x00]); // page 0: ACC_DATA_X_LSB (CONFIG: zero)
    write(&mut sim, 0x07, 1);
    assert_eq!(sim.page(), 1);
    assert_eq!(read(&mut sim, 0x08, 1), [0x0D]); // page 1: ACC_Config
    assert_eq!(read(&mut sim, 0x00, 1), [0x00]); // page 1 has no CHIP_ID
    write(&mut sim, 0x07, 2); // not a page: ignored
    assert_eq!(sim.page(), 1);
    write(&mut sim, 0x07, 0);
    assert_eq!(read(&mut sim, 0x00, 1), [0xA0]);
}

#[test]
fn configuration_writes_are_ignored_outside_config_mode() {
    let mut sim = sim();
    write(&mut sim, 0x3D, 0x07); // AMG
    assert_eq!(sim.operation_mode(), 0x07);
    write(&mut sim, 0x3B, 0x02); // UNIT_SEL
    write(&mut sim, 0x07, 1);
    write(&mut sim, 0x08, 0x1C); // ACC_Config
    write(&mut sim, 0x0A, 0x12); // GYR_Config_0
    write(&mut sim, 0x0B, 0x01); // GYR_Config_1
    write(&mut sim, 0x0F, 0x44); // INT_MSK: writable in any mode
    assert_eq!(sim.ignored_write_count(), 4);
    assert_eq!(read(&mut sim, 0x08, 4), [0x0D, 0x6D, 0x38, 0x00]);
    assert_eq!(sim.register(1, 0x0F), 0x44);
    assert_eq!(sim.register(0, 0x3B), 0x80);

    // OPR_MODE lives on page 0: back to CONFIG, then the same writes stick.
    write(&mut sim, 0x07, 0);
    write(&mut sim, 0x3D, 0x00);
    write(&mut sim, 0x3B, 0x02);
    write(&mut sim, 0x07, 1);
    write(&mut sim, 0x08, 0x1C);
    write(&mut sim, 0x0A, 0x12);
    write(&mut sim, 0x0B, 0x01);
    assert_eq!(read(&mut sim, 0x08, 4), [0x1C, 0x6D, 0x12, 0x01]);
    assert_eq!(sim.register(0, 0x3B), 0x02);
    assert_eq!(sim.ignored_write_count(), 4);
}

#[test]
fn read_only_registers_ignore_writes() {
    let mut sim = sim();
    write(&mut sim, 0x00, 0x55); // CHIP_ID
    write(&mut sim, 0x08, 0x55); // ACC_DATA
    assert_eq!(sim.register(0, 0x00), 0xA0);
    assert_eq!(sim.register(0, 0x08), 0x00);
    assert_eq!(sim.ignored_write_count(), 2);
}

#[test]
fn amg_mode_serves_the_source_little_endian() {
    let mut sim = sim();
    write(&mut sim, 0x3D, 0x07);
    let r = reading();
    let data = read(&mut sim, 0x08, 18);
    let mut expected = std::vec::Vec::new();
    for v in r.accel.iter().chain(&r.mag).chain(&r.gyro) {
        expected.extend_from_slice(&le(*v));
    }
    assert_eq!(data, expected);
    assert_eq!(read(&mut sim, 0x34, 1), [(-7i8) as u8]);
    assert_eq!(read(&mut sim, 0x39, 1), [6]); // SYS_STATUS: running without fusion
                                              // One reading latched per burst starting at a data register.
    assert_eq!(sim.samples_latched(), 2);
    read(&mut sim, 0x00, 1);
    assert_eq!(sim.samples_latched(), 2);
}

#[test]
fn each_burst_latches_a_new_reading() {
    struct Counter(i16);
    impl SampleSource for Counter {
        fn sample(&mut self) -> RawReading {
            self.0 += 1;
            RawReading {
                accel: [self.0, 0, 0],
                ..RawReading::default()
            }
        }
    }
    let mut sim = Bno055Sim::new(ADDR, Counter(0));
    sim.write(ADDR, &[0x3D, 0x07]).unwrap();
    for k in 1..=5i16 {
        let mut buf = [0u8; 6];
        sim.write_read(ADDR, &[0x08], &mut buf).unwrap();
        assert_eq!(i16::from_le_bytes([buf[0], buf[1]]), k);
    }
    // The second byte of a burst comes from the same reading.
    let mut buf = [0u8; 2];
    sim.write_read(ADDR, &[0x08], &mut buf).unwrap();
    assert_eq!(i16::from_le_bytes(buf), 6);
}

#[test]
fn enabled_sensors_follow_the_mode() {
    let mut sim = sim();
    write(&mut sim, 0x3D, 0x01); // ACC_ONLY
    let data = read(&mut sim, 0x08, 18);
    assert_eq!(&data[0..2], &le(-981));
    assert!(data[6..].iter().all(|&b| b == 0), "mag and gyro stay off");
    // Entering CONFIG mode zeroes the output data.
    write(&mut sim, 0x3D, 0x00);
    assert!(read(&mut sim, 0x08, 18).iter().all(|&b| b == 0));
    assert_eq!(sim.register(0, 0x39), 0); // SYS_STATUS idle
                                          // CONFIG mode: sensors off, no reading taken.
    let latched = sim.samples_latched();
    read(&mut sim, 0x08, 6);
    assert_eq!(sim.samples_latched(), latched);
}

#[test]
fn burst_writes_auto_increment() {
    let mut sim = sim();
    sim.write(ADDR, &[0x41, 0x21, 0x04]).unwrap(); // AXIS_MAP_CONFIG, AXIS_MAP_SIGN
    assert_eq!(read(&mut sim, 0x41, 2), [0x21, 0x04]);
}

#[test]
fn system_reset_restores_defaults_and_can_be_busy() {
    let mut sim = sim();
    sim.set_reset_busy(3);
    write(&mut sim, 0x3B, 0x02);
    write(&mut sim, 0x3D, 0x07);
    write(&mut sim, 0x07, 1);
    write(&mut sim, 0x3F, 0x20); // page 1 has no SYS_TRIGGER: ignored
    assert_eq!(sim.reset_count(), 0);
    write(&mut sim, 0x07, 0);
    write(&mut sim, 0x3F, 0x20);
    assert_eq!(sim.reset_count(), 1);
    let mut buf = [0u8; 1];
    for _ in 0..3 {
        assert_eq!(
            sim.write_read(ADDR, &[0x3D], &mut buf),
            Err(SimError::NoAcknowledge)
        );
    }
    assert_eq!(read(&mut sim, 0x3D, 1), [0x00]); // CONFIG
    assert_eq!(read(&mut sim, 0x3B, 1), [0x80]); // UNIT_SEL default
    assert_eq!(sim.page(), 0);
}

#[test]
fn booting_chip_refuses_then_answers_and_failures_have_no_effect() {
    let mut sim = Bno055Sim::new(ADDR, ConstantSource(reading())).booting_for(2);
    assert_eq!(sim.write(ADDR, &[0x3B, 0x01]), Err(SimError::NoAcknowledge));
    assert_eq!(sim.write(ADDR, &[0x3B, 0x01]), Err(SimError::NoAcknowledge));
    assert_eq!(sim.register(0, 0x3B), 0x80);
    write(&mut sim, 0x3B, 0x01);
    assert_eq!(sim.register(0, 0x3B), 0x01);

    sim.fail_next(1);
    let err = sim.write(ADDR, &[0x3B, 0x02]).unwrap_err();
    assert_eq!(err, SimError::Injected);
    assert_eq!(err.kind(), ErrorKind::Bus);
    assert_eq!(sim.register(0, 0x3B), 0x01);
    assert_eq!(sim.transaction_count(), 4);
    assert_eq!(sim.failed_transaction_count(), 3);
}

struct NoDelay;
impl embedded_hal::delay::DelayNs for NoDelay {
    fn delay_ns(&mut self, _ns: u32) {}
}

#[test]
fn the_bno055_driver_runs_against_the_simulator() {
    let sim = sim();
    let mut driver = bno055::Bno055::new(sim).with_alternative_address();
    driver.init(&mut NoDelay).unwrap();
    let revision = driver.get_revision().unwrap();
    assert_eq!(revision.software, 0x0311);
    assert_eq!(revision.accelerometer, 0xFB);
    assert_eq!(revision.gyroscope, 0x0F);
    // Not available in CONFIG mode (the driver itself checks its cached mode).
    driver
        .set_mode(bno055::BNO055OperationMode::AMG, &mut NoDelay)
        .unwrap();
    let accel = driver.accel_data_fixed().unwrap();
    assert_eq!([accel.x, accel.y, accel.z], reading().accel);
    let gyro = driver.gyro_data_fixed().unwrap();
    assert_eq!([gyro.x, gyro.y, gyro.z], reading().gyro);
    assert_eq!(driver.temperature().unwrap(), -7);
    let sim = driver.destroy();
    assert_eq!(sim.reset_count(), 1);
    assert_eq!(sim.operation_mode(), 0x07);
}
