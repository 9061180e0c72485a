//! The gyro log the QEMU firmware replays: a 16-byte header then fixed-size samples, all
//! little-endian, so the firmware reads it with no parsing library and no allocation.
//!
//! ```text
//! offset 0  magic  b"GYLG"
//!        4  u32    version (1)
//!        8  f32    sample rate, Hz
//!       12  u32    number of samples n
//!       16  n x [f32; 3]  angular rate, rad/s, sensor axes X Y Z
//! ```
//!
//! The samples are the gyro's input (true rate plus noise); the simulated part quantises them
//! at its configured full scale, as the real part would.

/// First four bytes of a log.
pub const MAGIC: [u8; 4] = *b"GYLG";
/// Format version written by this code.
pub const VERSION: u32 = 1;
/// Header length in bytes.
pub const HEADER_LEN: usize = 16;
/// One sample's length in bytes.
pub const SAMPLE_LEN: usize = 12;

/// The log's header.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Header {
    /// Sample rate, Hz.
    pub rate_hz: f32,
    /// Number of samples after the header.
    pub samples: u32,
}

/// Why a header was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum LogError {
    /// Not a gyro log.
    BadMagic,
    /// A version this code does not read.
    BadVersion(u32),
    /// Sample rate not positive and finite.
    BadRate,
}

fn word(b: &[u8; HEADER_LEN], at: usize) -> [u8; 4] {
    let mut w = [0u8; 4];
    for (i, x) in w.iter_mut().enumerate() {
        *x = b.get(at + i).copied().unwrap_or(0);
    }
    w
}

impl Header {
    /// Encodes the header.
    pub fn encode(&self) -> [u8; HEADER_LEN] {
        let mut b = [0u8; HEADER_LEN];
        let parts = [
            MAGIC,
            VERSION.to_le_bytes(),
            self.rate_hz.to_le_bytes(),
            self.samples.to_le_bytes(),
        ];
        for (dst, src) in b.chunks_exact_mut(4).zip(parts.iter()) {
            dst.copy_from_slice(src);
        }
        b
    }

    /// Decodes and checks a header.
    pub fn decode(b: &[u8; HEADER_LEN]) -> Result<Self, LogError> {
        if word(b, 0) != MAGIC {
            return Err(LogError::BadMagic);
        }
        let version = u32::from_le_bytes(word(b, 4));
        if version != VERSION {
            return Err(LogError::BadVersion(version));
        }
        let rate_hz = f32::from_le_bytes(word(b, 8));
        if !(rate_hz.is_finite() && rate_hz > 0.0) {
            return Err(LogError::BadRate);
        }
        Ok(Header {
            rate_hz,
            samples: u32::from_le_bytes(word(b, 12)),
        })
    }
}

/// Encodes one sample.
pub fn encode_sample(w: [f32; 3]) -> [u8; SAMPLE_LEN] {
    let mut b = [0u8; SAMPLE_LEN];
    for (dst, x) in b.chunks_exact_mut(4).zip(w.iter()) {
        dst.copy_from_slice(&x.to_le_bytes());
    }
    b
}

/// Decodes one sample.
pub fn decode_sample(b: &[u8; SAMPLE_LEN]) -> [f32; 3] {
    let mut w = [0.0f32; 3];
    for (x, src) in w.iter_mut().zip(b.chunks_exact(4)) {
        let mut q = [0u8; 4];
        q.copy_from_slice(src);
        *x = f32::from_le_bytes(q);
    }
    w
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_and_refusals() {
        let h = Header {
            rate_hz: 1000.0,
            samples: 20_000,
        };
        assert_eq!(Header::decode(&h.encode()), Ok(h));
        let mut bad = h.encode();
        bad[0] = b'X';
        assert_eq!(Header::decode(&bad), Err(LogError::BadMagic));
        let mut bad = h.encode();
        bad[4] = 2;
        assert_eq!(Header::decode(&bad), Err(LogError::BadVersion(2)));
        let w = [1.5f32, -0.25, f32::MIN_POSITIVE];
        assert_eq!(decode_sample(&encode_sample(w)), w);
    }
}
