//! The MPU-6050's register addresses and the bits within them, as the register map names
//! them \[RM\]: one home, shared by the firmware's driver and the host's simulated chip, so
//! both speak of one chip.

pub const SMPLRT_DIV: u8 = 0x19;
pub const CONFIG: u8 = 0x1A;
pub const GYRO_CONFIG: u8 = 0x1B;
pub const ACCEL_CONFIG: u8 = 0x1C;
pub const FIFO_EN: u8 = 0x23;
pub const INT_PIN_CFG: u8 = 0x37;
pub const INT_ENABLE: u8 = 0x38;
pub const INT_STATUS: u8 = 0x3A;
pub const ACCEL_XOUT_H: u8 = 0x3B;
pub const TEMP_OUT_H: u8 = 0x41;
pub const GYRO_XOUT_H: u8 = 0x43;
pub const SIGNAL_PATH_RESET: u8 = 0x68;
pub const USER_CTRL: u8 = 0x6A;
pub const PWR_MGMT_1: u8 = 0x6B;
pub const PWR_MGMT_2: u8 = 0x6C;
pub const FIFO_COUNT_H: u8 = 0x72;
pub const FIFO_R_W: u8 = 0x74;
pub const WHO_AM_I: u8 = 0x75;

/// Bits within the registers above, under the register map's names \[RM\].
pub mod bits {
    /// PWR_MGMT_1 [RM, reg 107]: reset every register (self-clearing); sleep (set after a
    /// reset).
    pub const DEVICE_RESET: u8 = 1 << 7;
    pub const SLEEP: u8 = 1 << 6;
    /// SIGNAL_PATH_RESET [RM, reg 104]: the gyro, accel and temperature signal paths.
    pub const GYRO_RESET: u8 = 1 << 2;
    pub const ACCEL_RESET: u8 = 1 << 1;
    pub const TEMP_RESET: u8 = 1 << 0;
    pub const SIGNAL_PATH_RESET_ALL: u8 = GYRO_RESET | ACCEL_RESET | TEMP_RESET;
    /// USER_CTRL [RM, reg 106]: FIFO_EN (named USER_FIFO_EN here, apart from the FIFO_EN
    /// register), FIFO_RESET and SIG_COND_RESET (both self-clearing).
    pub const USER_FIFO_EN: u8 = 1 << 6;
    pub const FIFO_RESET: u8 = 1 << 2;
    pub const SIG_COND_RESET: u8 = 1 << 0;
    /// INT_ENABLE [RM, reg 56] and INT_STATUS [RM, reg 58]: data ready, FIFO overflow.
    pub const DATA_RDY: u8 = 1 << 0;
    pub const FIFO_OFLOW: u8 = 1 << 4;
    /// FIFO_EN [RM, reg 35]: which sensors' data enter the FIFO.
    pub const TEMP_FIFO_EN: u8 = 1 << 7;
    pub const XG_FIFO_EN: u8 = 1 << 6;
    pub const YG_FIFO_EN: u8 = 1 << 5;
    pub const ZG_FIFO_EN: u8 = 1 << 4;
    pub const ACCEL_FIFO_EN: u8 = 1 << 3;
    /// Temperature, gyro x/y/z and accel: the 14-byte sample of
    /// [`crate::RawSample::from_fifo_bytes`].
    pub const FIFO_EN_ALL: u8 = TEMP_FIFO_EN | XG_FIFO_EN | YG_FIFO_EN | ZG_FIFO_EN | ACCEL_FIFO_EN;
}
