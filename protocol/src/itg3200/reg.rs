//! The ITG-3200's register addresses and bits, under the product specification's names
//! \[IT, section 8\].

pub const WHO_AM_I: u8 = 0x00;
pub const SMPLRT_DIV: u8 = 0x15;
pub const DLPF_FS: u8 = 0x16;
pub const INT_CFG: u8 = 0x17;
pub const INT_STATUS: u8 = 0x1A;
pub const TEMP_OUT_H: u8 = 0x1B;
pub const GYRO_XOUT_H: u8 = 0x1D;
pub const PWR_MGM: u8 = 0x3E;

/// Bits within the registers above.
pub mod bits {
    /// DLPF_FS bits 4:3: FS_SEL must be 3 for proper operation \[IT, reg 22\].
    pub const FS_SEL_2000: u8 = 0b11 << 3;
    /// DLPF_FS bits 2:0.
    pub const DLPF_CFG_MASK: u8 = 0b111;
    /// INT_CFG: the interrupt latches until cleared; any register read clears it; it fires
    /// when a new sample is ready \[IT, reg 23\].
    pub const LATCH_INT_EN: u8 = 1 << 5;
    pub const INT_ANYRD_2CLEAR: u8 = 1 << 4;
    pub const RAW_RDY_EN: u8 = 1 << 0;
    /// INT_STATUS: a new sample is in the data registers \[IT, reg 26\].
    pub const RAW_DATA_RDY: u8 = 1 << 0;
    /// PWR_MGM: reset every register (self-clearing); sleep; clock from the X gyro's PLL,
    /// which the specification recommends over the internal oscillator \[IT, reg 62\].
    pub const H_RESET: u8 = 1 << 7;
    pub const SLEEP: u8 = 1 << 6;
    pub const CLK_SEL_PLL_X: u8 = 0b001;
}

/// Bytes of one sample as one burst read from TEMP_OUT_H: temperature, then x, y, z, each
/// big-endian.
pub const SAMPLE_BYTES: usize = 8;
