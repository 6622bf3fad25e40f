//! [`Bno055Bus`]: one I²C bus with one or two simulated BNO055, as a board
//! with two breakouts at 0x28 and 0x29 has.

use embedded_hal::i2c::{ErrorType, I2c, Operation, SevenBitAddress};

use crate::{Bno055Sim, SampleSource, SimError};

/// Up to two [`Bno055Sim`] sharing one bus: a transaction goes to the chip
/// at its address; no chip there does not acknowledge
/// ([`SimError::NoAcknowledge`]), as on a real bus.
#[derive(Debug, Clone)]
pub struct Bno055Bus<Src> {
    chips: [Option<Bno055Sim<Src>>; 2],
}

impl<Src: SampleSource> Bno055Bus<Src> {
    /// A bus with one chip.
    pub fn one(chip: Bno055Sim<Src>) -> Self {
        Self {
            chips: [Some(chip), None],
        }
    }

    /// A bus with two chips (at different addresses).
    pub fn two(first: Bno055Sim<Src>, second: Bno055Sim<Src>) -> Self {
        Self {
            chips: [Some(first), Some(second)],
        }
    }

    /// Chip `i` (0 or 1, in the order given), if there is one.
    pub fn chip(&self, i: usize) -> Option<&Bno055Sim<Src>> {
        self.chips.get(i).and_then(Option::as_ref)
    }

    /// Chip `i`, mutably.
    pub fn chip_mut(&mut self, i: usize) -> Option<&mut Bno055Sim<Src>> {
        self.chips.get_mut(i).and_then(Option::as_mut)
    }

    /// The chips, in order.
    pub fn chips_mut(&mut self) -> impl Iterator<Item = &mut Bno055Sim<Src>> {
        self.chips.iter_mut().flatten()
    }

    /// Runs every chip's internal clocks up to now ([`Bno055Sim::advance`]).
    pub fn advance(&mut self) {
        self.chips_mut().for_each(Bno055Sim::advance);
    }

    /// Gives the chips back.
    pub fn into_chips(self) -> [Option<Bno055Sim<Src>>; 2] {
        self.chips
    }
}

impl<Src> ErrorType for Bno055Bus<Src> {
    type Error = SimError;
}

impl<Src: SampleSource> I2c<SevenBitAddress> for Bno055Bus<Src> {
    fn transaction(
        &mut self,
        address: SevenBitAddress,
        operations: &mut [Operation<'_>],
    ) -> Result<(), Self::Error> {
        match self
            .chips
            .iter_mut()
            .flatten()
            .find(|c| c.address() == address)
        {
            Some(chip) => chip.transaction(address, operations),
            None => Err(SimError::NoAcknowledge),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ConstantSource;

    /// Each chip answers at its own address only, with its own registers;
    /// an empty address is not acknowledged and touches neither chip.
    #[test]
    fn transactions_go_to_the_chip_at_their_address() {
        let mut bus = Bno055Bus::two(
            Bno055Sim::new(0x28, ConstantSource::default()),
            Bno055Sim::new(0x29, ConstantSource::default()),
        );
        bus.write(0x29, &[crate::regs::PAGE_ID, 1]).unwrap();
        assert_eq!(bus.chip(0).unwrap().page(), 0);
        assert_eq!(bus.chip(1).unwrap().page(), 1);
        let mut id = [0u8];
        bus.write_read(0x28, &[crate::regs::CHIP_ID], &mut id)
            .unwrap();
        assert_eq!(id, [0xA0]);
        assert_eq!(
            bus.write_read(0x30, &[crate::regs::CHIP_ID], &mut id),
            Err(SimError::NoAcknowledge)
        );
        assert_eq!(bus.chip(0).unwrap().transaction_count(), 1);
        assert_eq!(bus.chip(1).unwrap().transaction_count(), 1);
        let mut one = Bno055Bus::one(Bno055Sim::new(0x28, ConstantSource::default()));
        assert_eq!(
            one.write_read(0x29, &[crate::regs::CHIP_ID], &mut id),
            Err(SimError::NoAcknowledge)
        );
        assert!(one.chip(1).is_none());
    }
}
