//! The exact I²C transactions of boot and of sample reads, pinned with
//! embedded-hal-mock (register values from the BNO055 datasheet, section 4).

mod support;

use embedded_hal::i2c::{ErrorKind, NoAcknowledgeSource};
use embedded_hal_mock::eh1::delay::{CheckedDelay, Transaction as Delay};
use embedded_hal_mock::eh1::i2c::{Mock as I2cMock, Transaction as T};
use robimu_firmware::{Acquisition, Config, Error};
use robimu_protocol::{DeviceDecoder, DeviceMessage, ImuSample};
use support::{Link, SimTime};

const A: u8 = 0x28;

/// Boot of a ready chip with the default settings (±4 g / 62.5 Hz,
/// ±2000 °/s / 116 Hz), through the `bno055` driver and the core's own writes.
fn boot_transactions() -> Vec<T> {
    vec![
        // bno055::init: PAGE_ID = 0, then id(): PAGE_ID = 0 again, CHIP_ID
        T::write(A, vec![0x07, 0x00]),
        T::write(A, vec![0x07, 0x00]),
        T::write_read(A, vec![0x00], vec![0xA0]),
        // soft reset: PAGE_ID = 0, SYS_TRIGGER.RST_SYS
        T::write(A, vec![0x07, 0x00]),
        T::write(A, vec![0x3F, 0x20]),
        // (already in CONFIG mode) PWR_MODE normal, SYS_TRIGGER cleared
        T::write(A, vec![0x07, 0x00]),
        T::write(A, vec![0x3E, 0x00]),
        T::write(A, vec![0x3F, 0x00]),
        // get_revision: ACC_ID, MAG_ID, GYR_ID, SW_REV LSB/MSB, BL_REV
        T::write(A, vec![0x07, 0x00]),
        T::write_read(A, vec![0x01], vec![0xFB, 0x32, 0x0F, 0x11, 0x03, 0x15]),
        // set_acc_config on page 1: ACC_Config = 0b011_01
        T::write(A, vec![0x07, 0x01]),
        T::write(A, vec![0x08, 0x0D]),
        // core: GYR_Config_0 = 0b010_000 (116 Hz, ±2000 °/s), GYR_Config_1 normal
        T::write(A, vec![0x0A, 0x10]),
        T::write(A, vec![0x0B, 0x00]),
        // read back ACC_Config, MAG_Config, GYR_Config_0, GYR_Config_1
        T::write_read(A, vec![0x08], vec![0x0D, 0x6D, 0x10, 0x00]),
        // page 0, UNIT_SEL = m/s², rad/s, °C, read back
        T::write(A, vec![0x07, 0x00]),
        T::write(A, vec![0x3B, 0x02]),
        T::write_read(A, vec![0x3B], vec![0x02]),
        // set_mode(AMG), check OPR_MODE
        T::write(A, vec![0x07, 0x00]),
        T::write(A, vec![0x3D, 0x07]),
        T::write_read(A, vec![0x3D], vec![0x07]),
    ]
}

fn boot_delays() -> Vec<Delay> {
    vec![Delay::delay_ms(650), Delay::delay_ms(19)]
}

fn decode(bytes: &[u8]) -> Vec<DeviceMessage> {
    let mut decoder = DeviceDecoder::new();
    decoder.feed(bytes).map(|m| m.unwrap()).collect()
}

fn samples(messages: &[DeviceMessage]) -> Vec<ImuSample> {
    messages
        .iter()
        .filter_map(|m| match m {
            DeviceMessage::Sample(s) => Some(*s),
            _ => None,
        })
        .collect()
}

/// 18 data bytes: accel (1, -2, 3), mag (0x5555 ×3), gyro (900, -900, 16).
fn amg_bytes(accel_x: i16) -> Vec<u8> {
    let mut bytes = Vec::new();
    for v in [accel_x, -2, 3, 0x5555, 0x5555, 0x5555, 900, -900, 16] {
        bytes.extend_from_slice(&v.to_le_bytes());
    }
    bytes
}

#[test]
fn boot_and_two_samples_use_exactly_these_transactions() {
    let mut expected = boot_transactions();
    // First sample: one 18-byte burst from ACC_DATA_X_LSB, then TEMP.
    expected.push(T::write_read(A, vec![0x08], amg_bytes(1)));
    expected.push(T::write_read(A, vec![0x34], vec![0xF9])); // -7 °C
                                                             // Second sample: the burst only (temperature once a second).
    expected.push(T::write_read(A, vec![0x08], amg_bytes(4)));
    // Third: the burst fails once and is retried at once.
    expected.push(T::write_read(A, vec![0x08], amg_bytes(0)).with_error(ErrorKind::Bus));
    expected.push(T::write_read(A, vec![0x08], amg_bytes(5)));
    let mut i2c = I2cMock::new(&expected);
    let mut delay = CheckedDelay::new(&boot_delays());
    let time = SimTime::starting_at(10);
    let link = Link::new();
    let config = Config {
        autostart: true,
        status_period_ms: 0,
        ..Config::default()
    };
    let mut core = Acquisition::new(
        i2c.clone(),
        delay.clone(),
        link.clone(),
        time.clone(),
        config,
    );
    core.start().unwrap();
    assert_eq!(core.next_deadline_us(), Some(10));
    core.poll(); // sample 0 at t = 10
    assert_eq!(core.next_deadline_us(), Some(10 + 6_666));
    time.advance(6_666); // floor(10⁶ / 150), the default rate
    core.poll();
    time.advance(1);
    core.poll(); // not due: nothing on the bus
    time.advance(6_666);
    core.poll();
    let (_, _, _, _) = core.release();
    i2c.done();
    delay.done();

    let messages = decode(&link.take_sent());
    assert!(matches!(messages[0], DeviceMessage::Info(_)));
    let samples = samples(&messages);
    assert_eq!(
        samples[0],
        ImuSample {
            sensor: 0,
            seq: 0,
            t_us: 10,
            accel_raw: [1, -2, 3],
            gyro_raw: [900, -900, 16],
            temp_raw: -7,
        }
    );
    assert_eq!(samples[1].t_us, 10 + 6_666);
    assert_eq!(samples[1].accel_raw, [4, -2, 3]);
    assert_eq!(samples[1].temp_raw, -7, "the last temperature is repeated");
    assert_eq!(samples[2].seq, 2);
    assert_eq!(samples[2].t_us, 10 + 13_333); // floor(2·10⁶ / 150)
    assert_eq!(samples[2].accel_raw, [5, -2, 3]);
    assert_eq!(samples.len(), 3);
}

#[test]
fn boot_retries_every_10_ms_until_the_timeout_on_address_0x29() {
    let b = 0x29;
    let nack = ErrorKind::NoAcknowledge(NoAcknowledgeSource::Address);
    // Each attempt stops at its first transaction (PAGE_ID = 0).
    let expected = vec![T::write(b, vec![0x07, 0x00]).with_error(nack); 3];
    let mut i2c = I2cMock::new(&expected);
    let mut delay = CheckedDelay::new(&[Delay::delay_ms(10), Delay::delay_ms(10)]);
    let link = Link::new();
    let config = Config {
        i2c_address: b,
        boot_timeout_ms: 20,
        ..Config::default()
    };
    let mut core = Acquisition::new(
        i2c.clone(),
        delay.clone(),
        link.clone(),
        SimTime::default(),
        config,
    );
    assert_eq!(core.start(), Err(Error::Bus(nack)));
    drop(core);
    i2c.done();
    delay.done();
    assert!(matches!(
        decode(&link.take_sent())[..],
        [DeviceMessage::Info(_)]
    ));
}

#[test]
fn a_configuration_the_chip_did_not_take_is_reported() {
    let mut expected = boot_transactions();
    expected.truncate(14);
    // GYR_Config_0 still at its reset value 0x38: the write was ignored.
    expected.push(T::write_read(A, vec![0x08], vec![0x0D, 0x6D, 0x38, 0x00]));
    let mut i2c = I2cMock::new(&expected);
    let mut delay = CheckedDelay::new(&[Delay::delay_ms(650)]);
    let mut core = Acquisition::new(
        i2c.clone(),
        delay.clone(),
        Link::new(),
        SimTime::default(),
        Config::default(),
    );
    assert_eq!(
        core.start(),
        Err(Error::NotApplied {
            page: 1,
            register: 0x0A,
            wrote: 0x10,
            read: 0x38
        })
    );
    assert!(!core.sensor_ready());
    drop(core);
    i2c.done();
    delay.done();
}
