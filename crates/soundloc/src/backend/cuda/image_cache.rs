//! Compiled kernel images kept on disk between runs, beside the prepared transfer
//! functions ([`crate::array::tf_cache`]): NVRTC takes 80–130 ms per process for the one
//! module a backend loads, which a warm run need not pay.
//!
//! - **Key.** A 64-bit FNV-1a hash of the whole translation unit, the NVRTC options (the
//!   target architecture and any tuning `-D`s), NVRTC's version and the device's compute
//!   capability: a changed kernel, compiler or option is a different entry.
//! - **Entry.** `DIR/cuda-<key>.bin`: magic `SLCUDAIMG1\n`, the architecture string
//!   (u32 length + bytes), the image length (u64), its CRC-32 (u32), the image (CUBIN or
//!   NUL-terminated PTX). A wrong magic, length or checksum is a miss and the entry is
//!   rewritten; writing is atomic ([`crate::array::tf_cache::write_atomic`]).
//! - A folder that cannot be read or written only costs the compilation. The folder's size
//!   limit and least-recently-used deletion are the TF cache's ([`crate::array::tf_cache::prune`]).

use super::kernels::Image;
use crate::array::tf_cache::{fnv1a, max_bytes, prune, touch, write_atomic, FNV_START};
use std::path::{Path, PathBuf};

const MAGIC: &[u8; 11] = b"SLCUDAIMG1\n";

/// The entry file in `dir` for this source, options, compiler and device.
pub(crate) fn entry(dir: &Path, source: &str, options: &[String], nvrtc: (i32, i32), cc: u32) -> PathBuf {
    let h = key(
        &format!("soundloc cuda image v1 nvrtc {}.{} cc {cc}\n", nvrtc.0, nvrtc.1),
        source,
        options,
    );
    dir.join(format!("cuda-{h:016x}.bin"))
}

/// A 64-bit FNV-1a hash of `header`, the NVRTC `options` and the translation unit: the key
/// of a compiled image (here and in [`super::prebuilt`]).
pub(crate) fn key(header: &str, source: &str, options: &[String]) -> u64 {
    let mut h = FNV_START;
    fnv1a(&mut h, header.as_bytes());
    for o in options {
        fnv1a(&mut h, o.as_bytes());
        fnv1a(&mut h, b"\0");
    }
    fnv1a(&mut h, source.as_bytes());
    h
}

/// The image stored in `file`, or why it cannot be used (absent, torn, corrupt).
pub(crate) fn read(file: &Path) -> Result<Image, String> {
    let raw = std::fs::read(file).map_err(|e| e.to_string())?;
    let bad = || "not a complete kernel image entry".to_string();
    let rest = raw.strip_prefix(MAGIC.as_slice()).ok_or_else(bad)?;
    let (n, rest) = take(rest, 4).ok_or_else(bad)?;
    let n = u32::from_le_bytes(n.try_into().map_err(|_| bad())?) as usize;
    let (arch, rest) = take(rest, n).ok_or_else(bad)?;
    let arch = std::str::from_utf8(arch).map_err(|_| bad())?.to_string();
    let (len, rest) = take(rest, 8).ok_or_else(bad)?;
    let len = u64::from_le_bytes(len.try_into().map_err(|_| bad())?) as usize;
    let (crc, rest) = take(rest, 4).ok_or_else(bad)?;
    let crc = u32::from_le_bytes(crc.try_into().map_err(|_| bad())?);
    if rest.len() != len || len == 0 {
        return Err(bad());
    }
    if crc32fast::hash(rest) != crc {
        return Err("kernel image entry fails its checksum".into());
    }
    if !arch.starts_with("sm_") && rest.last() != Some(&0) {
        return Err("PTX entry is not NUL-terminated".into());
    }
    touch(file);
    Ok(Image {
        bytes: rest.to_vec(),
        arch,
        prebuilt: false,
    })
}

fn take(b: &[u8], n: usize) -> Option<(&[u8], &[u8])> {
    (b.len() >= n).then(|| b.split_at(n))
}

/// Store `img` as `file` (in `dir`).
pub(crate) fn write(dir: &Path, file: &Path, img: &Image) -> std::io::Result<()> {
    let arch = img.arch.as_bytes();
    write_atomic(
        dir,
        file,
        &[
            MAGIC,
            &(arch.len() as u32).to_le_bytes(),
            arch,
            &(img.bytes.len() as u64).to_le_bytes(),
            &crc32fast::hash(&img.bytes).to_le_bytes(),
            &img.bytes,
        ],
    )?;
    prune(dir, file, max_bytes());
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dir(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("soundloc-image-cache-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        d
    }

    #[test]
    fn an_entry_round_trips_and_damage_is_a_miss() {
        let d = dir("rt");
        let opts = vec!["--gpu-architecture=sm_90".to_string()];
        let f = entry(&d, "extern \"C\" __global__ void k() {}", &opts, (13, 0), 90);
        assert!(read(&f).is_err(), "absent entry");
        let img = Image {
            bytes: (0..5000u32).map(|i| (i * 7 % 251) as u8).collect(),
            arch: "sm_90".into(),
            prebuilt: false,
        };
        write(&d, &f, &img).unwrap();
        let back = read(&f).unwrap();
        assert_eq!((back.bytes, back.arch), (img.bytes.clone(), img.arch.clone()));
        // Every truncation and a flipped byte in the image are misses, never a wrong image.
        let raw = std::fs::read(&f).unwrap();
        for cut in [0, 5, 11, 20, raw.len() - 1] {
            std::fs::write(&f, &raw[..cut]).unwrap();
            assert!(read(&f).is_err(), "truncated at {cut}");
        }
        let mut flipped = raw.clone();
        let last = flipped.len() - 10;
        flipped[last] ^= 0x40;
        std::fs::write(&f, &flipped).unwrap();
        assert!(read(&f).unwrap_err().contains("checksum"));
        // Different source, options, compiler or device: a different entry.
        let other = [
            entry(&d, "extern \"C\" __global__ void k2() {}", &opts, (13, 0), 90),
            entry(
                &d,
                "extern \"C\" __global__ void k() {}",
                &["-DX=1".to_string()],
                (13, 0),
                90,
            ),
            entry(&d, "extern \"C\" __global__ void k() {}", &opts, (12, 8), 90),
            entry(&d, "extern \"C\" __global__ void k() {}", &opts, (13, 0), 80),
        ];
        for o in other {
            assert_ne!(o, f);
        }
        let _ = std::fs::remove_dir_all(&d);
    }
}
