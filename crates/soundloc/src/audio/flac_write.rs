//! A minimal FLAC writer for fixtures and tests.

/// Encode `channels` (one slice of integer samples per channel, `bps` bits) as a FLAC
/// stream: STREAMINFO, then frames of 1024 samples with verbatim (uncompressed) subframes
/// and correct CRC-8/CRC-16. Any FLAC decoder reads it; it is for fixtures and tests (no
/// compression).
pub fn encode_flac_verbatim(sample_rate: u32, bps: u32, channels: &[Vec<i32>]) -> Vec<u8> {
    struct Bits {
        out: Vec<u8>,
        acc: u64,
        n: u32,
    }
    impl Bits {
        fn put(&mut self, v: u64, bits: u32) {
            for i in (0..bits).rev() {
                self.acc = (self.acc << 1) | ((v >> i) & 1);
                self.n += 1;
                if self.n == 8 {
                    self.out.push(self.acc as u8);
                    self.acc = 0;
                    self.n = 0;
                }
            }
        }
        fn align(&mut self) {
            while self.n != 0 {
                self.put(0, 1);
            }
        }
    }
    fn crc8(d: &[u8]) -> u8 {
        let mut c = 0u8;
        for &b in d {
            c ^= b;
            for _ in 0..8 {
                c = if c & 0x80 != 0 { (c << 1) ^ 0x07 } else { c << 1 };
            }
        }
        c
    }
    fn crc16(d: &[u8]) -> u16 {
        let mut c = 0u16;
        for &b in d {
            c ^= (b as u16) << 8;
            for _ in 0..8 {
                c = if c & 0x8000 != 0 {
                    (c << 1) ^ 0x8005
                } else {
                    c << 1
                };
            }
        }
        c
    }
    let nch = channels.len();
    let total = channels[0].len();
    let block = 1024usize;
    let mut b = Bits {
        out: b"fLaC".to_vec(),
        acc: 0,
        n: 0,
    };
    b.put(1, 1); // last metadata block
    b.put(0, 7); // STREAMINFO
    b.put(34, 24);
    b.put(block as u64, 16);
    b.put(block as u64, 16);
    b.put(0, 24);
    b.put(0, 24);
    b.put(sample_rate as u64, 20);
    b.put(nch as u64 - 1, 3);
    b.put(bps as u64 - 1, 5);
    b.put(total as u64, 36);
    b.put(0, 64);
    b.put(0, 64);
    for (fi, start) in (0..total).step_by(block).enumerate() {
        assert!(fi < 128);
        let len = block.min(total - start);
        let frame_start = b.out.len();
        b.put(0b11_1111_1111_1110, 14);
        b.put(0, 1);
        b.put(0, 1); // fixed block size
        b.put(0b0111, 4); // 16-bit block size - 1 at end of header
        b.put(0b0000, 4); // sample rate from STREAMINFO
        b.put(nch as u64 - 1, 4); // independent channels
        b.put(if bps == 16 { 0b100 } else { 0b110 }, 3);
        b.put(0, 1);
        b.put(fi as u64, 8); // UTF-8 frame number (< 128)
        b.put(len as u64 - 1, 16);
        let c8 = crc8(&b.out[frame_start..]);
        b.put(c8 as u64, 8);
        for ch in channels {
            b.put(0, 1);
            b.put(0b000001, 6); // VERBATIM
            b.put(0, 1);
            for &s in &ch[start..start + len] {
                b.put((s as i64 as u64) & ((1u64 << bps) - 1), bps);
            }
        }
        b.align();
        let c16 = crc16(&b.out[frame_start..]);
        b.put(c16 as u64, 16);
    }
    b.out
}
