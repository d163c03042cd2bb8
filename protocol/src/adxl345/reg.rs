//! The ADXL345's register addresses and bits, under the data sheet's names \[AD, table 19\].

pub const DEVID: u8 = 0x00;
pub const BW_RATE: u8 = 0x2C;
pub const POWER_CTL: u8 = 0x2D;
pub const INT_SOURCE: u8 = 0x30;
pub const DATA_FORMAT: u8 = 0x31;
pub const DATAX0: u8 = 0x32;
pub const FIFO_CTL: u8 = 0x38;
pub const FIFO_STATUS: u8 = 0x39;

/// Bits within the registers above.
pub mod bits {
    /// BW_RATE: reduced power at somewhat higher noise; bits 3:0 the rate code \[AD, reg
    /// 0x2C\].
    pub const LOW_POWER: u8 = 1 << 4;
    pub const RATE_MASK: u8 = 0x0F;
    /// POWER_CTL: measurement mode (standby when clear) \[AD, reg 0x2D\].
    pub const MEASURE: u8 = 1 << 3;
    /// INT_SOURCE: the FIFO overflowed (samples were overwritten) \[AD, reg 0x30\].
    pub const OVERRUN: u8 = 1 << 0;
    /// DATA_FORMAT: full resolution (3.9 mg/LSB in every range); bits 1:0 the range \[AD,
    /// reg 0x31\].
    pub const FULL_RES: u8 = 1 << 3;
    pub const RANGE_MASK: u8 = 0b11;
    /// FIFO_CTL bits 7:6: stream mode, the newest 32 samples kept \[AD, reg 0x38\].
    pub const FIFO_MODE_STREAM: u8 = 0b10 << 6;
    /// FIFO_STATUS bits 5:0: samples in the FIFO \[AD, reg 0x39\].
    pub const ENTRIES_MASK: u8 = 0x3F;
}

/// Bytes of one sample as one burst read from DATAX0: x, y, z, each little-endian.
pub const SAMPLE_BYTES: usize = 6;
