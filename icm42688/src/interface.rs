//! The two buses the ICM-42688-P speaks, behind one small trait so the driver logic exists
//! once. The part also has I3C; embedded-hal has no I3C trait.

use embedded_hal::i2c::I2c;
use embedded_hal::spi::{Operation, SpiDevice};

use crate::registers::SPI_READ;

/// Register access: write one register, burst-read consecutive registers.
pub trait RegisterInterface {
    /// The bus's error.
    type Error;
    /// True on SPI: the driver then disables the part's I2C interface (`INTF_CONFIG0`).
    const IS_SPI: bool = false;
    /// Writes `value` to register `reg` of the current bank.
    fn write_register(&mut self, reg: u8, value: u8) -> Result<(), Self::Error>;
    /// Reads `buf.len()` registers starting at `reg` (the part auto-increments the address,
    /// except on `FIFO_DATA`, which it pops).
    fn read_registers(&mut self, reg: u8, buf: &mut [u8]) -> Result<(), Self::Error>;
}

/// SPI (mode 0 or 3, up to 24 MHz): one `SpiDevice` transaction per access, chip select
/// held across the address byte and the data. Bit 7 of the address byte is the read flag.
#[derive(Debug)]
pub struct SpiInterface<SPI> {
    spi: SPI,
}

impl<SPI> SpiInterface<SPI> {
    /// Wraps an SPI device.
    pub const fn new(spi: SPI) -> Self {
        SpiInterface { spi }
    }

    /// The SPI device.
    pub fn bus(&self) -> &SPI {
        &self.spi
    }

    /// The SPI device, mutably.
    pub fn bus_mut(&mut self) -> &mut SPI {
        &mut self.spi
    }

    /// Gives the SPI device back.
    pub fn release(self) -> SPI {
        self.spi
    }
}

impl<SPI: SpiDevice> RegisterInterface for SpiInterface<SPI> {
    type Error = SPI::Error;
    const IS_SPI: bool = true;

    fn write_register(&mut self, reg: u8, value: u8) -> Result<(), Self::Error> {
        self.spi.write(&[reg & !SPI_READ, value])
    }

    fn read_registers(&mut self, reg: u8, buf: &mut [u8]) -> Result<(), Self::Error> {
        self.spi
            .transaction(&mut [Operation::Write(&[reg | SPI_READ]), Operation::Read(buf)])
    }
}

/// The 7-bit I2C address, set by the AP_AD0 pin.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum I2cAddress {
    /// AP_AD0 low: 0x68.
    Ad0Low = 0x68,
    /// AP_AD0 high: 0x69.
    Ad0High = 0x69,
}

/// I2C (up to 1 MHz): register address write then repeated-start read.
#[derive(Debug)]
pub struct I2cInterface<I2C> {
    i2c: I2C,
    address: u8,
}

impl<I2C> I2cInterface<I2C> {
    /// Wraps an I2C bus for the part at `address`.
    pub const fn new(i2c: I2C, address: I2cAddress) -> Self {
        I2cInterface {
            i2c,
            address: address as u8,
        }
    }

    /// Gives the I2C bus back.
    pub fn release(self) -> I2C {
        self.i2c
    }
}

impl<I2C: I2c> RegisterInterface for I2cInterface<I2C> {
    type Error = I2C::Error;

    fn write_register(&mut self, reg: u8, value: u8) -> Result<(), Self::Error> {
        self.i2c.write(self.address, &[reg, value])
    }

    fn read_registers(&mut self, reg: u8, buf: &mut [u8]) -> Result<(), Self::Error> {
        self.i2c.write_read(self.address, &[reg], buf)
    }
}
