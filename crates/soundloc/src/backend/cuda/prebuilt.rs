//! Kernel images compiled ahead of time and embedded in the binary: a backend on a GPU
//! they serve loads its module without NVRTC. No run-time compiler has to be installed
//! (with a CUDA 13 driver, 580 or later), and no run pays NVRTC's compilation of the
//! module (16–18 s on an H100 or H200 host, 2026-12-07; BENCHMARKS.md, "stop 60").
//!
//! - **Which GPUs.** One bundle per architecture ([`BUNDLES`]): sm_75 (T4, RTX 20xx),
//!   sm_80 (A100; its images also run on 8.6 and 8.9: A10, A40, RTX 30xx, L4, L40S,
//!   RTX 40xx), sm_90 (H100, H200), sm_100 (B200; also 10.3), sm_120 (RTX 50xx,
//!   RTX PRO 6000; also 12.1). A device takes the bundle of its own major version with the
//!   highest minor version not above its own ([`bundle_for`]): a cubin runs on any GPU
//!   of its major version and an equal or higher minor one.
//! - **Which kernels.** f32 (the default precision), the exact layout
//!   ([`Variant::exact_for_mics`]) of every array of 2 to 64 microphones: the tridiagonal
//!   eigensolver's range. f64, larger arrays and older GPUs compile with NVRTC as before
//!   ([`super::kernels::image_for`]).
//! - **Key.** A 64-bit FNV-1a hash of the bundle's compute capability, the NVRTC options
//!   and the whole translation unit: a changed kernel or a tuning `-D`
//!   (`SOUNDLOC_CUDA_NVRTC_OPTS`) is a miss, and NVRTC compiles. A test keeps every
//!   bundle current with the sources.
//! - **Bundle.** `kernels/prebuilt/sm_XY.bin`: magic `SLCUPRE2\n`, a base image (the
//!   middle variant's), then the entry count (u32) and per entry the key (u64), the compute
//!   capability (u32), the architecture string (u32 length + bytes), the image's length
//!   (u64) and CRC-32 (u32), and the image compressed with zstd (u64 length + bytes)
//!   against the base as a raw dictionary (the images of neighbouring layouts share most of
//!   their code: 2.1–2.2 MB for 32 images of ≈ 1 MB, against 9 MB deflated one by one).
//!   The base is stored as an image (length, CRC-32, zstd length, bytes) without a
//!   dictionary. Integers little-endian. A damaged entry is an error, and NVRTC compiles.
//! - **Written** by `soundloc cuda-prebuild --arch sm_XY -o FILE` (hidden) on any machine
//!   with NVRTC, a GPU or not: `scripts/cuda_prebuild.sh` regenerates every bundle with
//!   pip's `nvidia-cuda-nvrtc==13.0.88` (docs/gpu.md, "How to reproduce").

use super::kernels::{full_source, options, Image, Variant};

const MAGIC: &[u8; 9] = b"SLCUPRE2\n";

/// The embedded bundles: compute capability (major·10 + minor) and bytes, ascending.
pub(crate) static BUNDLES: &[(u32, &[u8])] = &[
    (75, include_bytes!("../../../kernels/prebuilt/sm_75.bin")),
    (80, include_bytes!("../../../kernels/prebuilt/sm_80.bin")),
    (90, include_bytes!("../../../kernels/prebuilt/sm_90.bin")),
    (100, include_bytes!("../../../kernels/prebuilt/sm_100.bin")),
    (120, include_bytes!("../../../kernels/prebuilt/sm_120.bin")),
];

/// The compute capability of the bundle whose images run on a device of compute
/// capability `cc`: the same major version, the highest minor version not above the
/// device's (8.6 and 8.9 take 8.0's; 9.0 its own; 7.0 none). `have` is ascending.
pub(crate) fn bundle_for(cc: u32, have: &[u32]) -> Option<u32> {
    have.iter()
        .copied()
        .filter(|&b| b / 10 == cc / 10 && b <= cc)
        .max()
}

/// The variants the bundle holds: f32, exact layouts for 2..=64 microphones.
pub(crate) fn variants() -> Vec<Variant> {
    (2..=64)
        .step_by(2)
        .filter_map(Variant::exact_for_mics)
        .map(|v| Variant { only: "f32", ..v })
        .collect()
}

/// The key of a translation unit compiled with `options` for compute capability `cc`.
pub(crate) fn key(source: &str, options: &[String], cc: u32) -> u64 {
    super::image_cache::key(
        &format!("soundloc prebuilt cuda image v1 cc {cc}\n"),
        source,
        options,
    )
}

/// One entry of a bundle.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Entry {
    pub key: u64,
    pub cc: u32,
    pub arch: String,
    pub image: Vec<u8>,
}

/// The embedded image for `v` on a device of compute capability `cc`, if the bundle has
/// one for these very sources and options.
pub(crate) fn find(v: Variant, cc: u32) -> Option<Image> {
    let ccs: Vec<u32> = BUNDLES.iter().map(|b| b.0).collect();
    let bcc = bundle_for(cc, &ccs)?;
    let bundle = BUNDLES.iter().find(|b| b.0 == bcc)?.1;
    let want = key(&full_source(v), &options(&format!("sm_{bcc}")), bcc);
    let e = match read_entry(bundle, want) {
        Ok(e) => e?,
        Err(why) => {
            tracing::debug!("embedded kernels: {why}");
            return None;
        }
    };
    Some(Image {
        bytes: e.image,
        arch: e.arch,
        prebuilt: true,
    })
}

/// Every entry of an embedded bundle (for its test).
#[cfg(test)]
pub(crate) fn embedded(bundle: &[u8]) -> Result<Vec<Entry>, String> {
    let (base, n, mut rest) = open(bundle)?;
    let base = base_image(base)?;
    let mut out = Vec::new();
    for _ in 0..n {
        let (e, r) = parse(rest, base.as_deref())?;
        out.push(e);
        rest = r;
    }
    Ok(out)
}

/// A bundle holding `entries` (the middle one's image is the base).
pub(crate) fn write(entries: &[Entry]) -> std::io::Result<Vec<u8>> {
    let base: &[u8] = entries.get(entries.len() / 2).map_or(&[], |e| &e.image);
    let mut out = MAGIC.to_vec();
    let z = zstd::bulk::compress(base, LEVEL)?;
    image_header(&mut out, base, &z);
    out.extend(z);
    out.extend((entries.len() as u32).to_le_bytes());
    let mut c = zstd::bulk::Compressor::with_dictionary(LEVEL, base)?;
    for e in entries {
        let z = c.compress(&e.image)?;
        out.extend(e.key.to_le_bytes());
        out.extend(e.cc.to_le_bytes());
        out.extend((e.arch.len() as u32).to_le_bytes());
        out.extend(e.arch.as_bytes());
        image_header(&mut out, &e.image, &z);
        out.extend(z);
    }
    Ok(out)
}

const LEVEL: i32 = 19;

fn image_header(out: &mut Vec<u8>, image: &[u8], z: &[u8]) {
    out.extend((image.len() as u64).to_le_bytes());
    out.extend(crc32fast::hash(image).to_le_bytes());
    out.extend((z.len() as u64).to_le_bytes());
}

/// A bundle opened: the base image's record (still compressed: it is decompressed only
/// for an entry that is used), the entry count and the entries' bytes.
type Opened<'a> = (&'a [u8], u32, &'a [u8]);

fn open(bundle: &[u8]) -> Result<Opened<'_>, String> {
    let rest = bundle
        .strip_prefix(MAGIC.as_slice())
        .ok_or("not a prebuilt kernel bundle")?;
    let (_, zlen) = take(rest, 12)?;
    let zlen = u64::from_le_bytes(take(zlen, 8)?.0.try_into().unwrap());
    let record = usize::try_from(zlen)
        .ok()
        .and_then(|z| z.checked_add(20))
        .ok_or("too long")?;
    let (base, rest) = take(rest, record)?;
    let (n, rest) = take(rest, 4)?;
    Ok((base, u32::from_le_bytes(n.try_into().unwrap()), rest))
}

/// The base image of an opened bundle (None in an empty one).
fn base_image(record: &[u8]) -> Result<Option<Vec<u8>>, String> {
    image(record, None).map(|(b, _)| b)
}

/// The image at the start of `b` (length, CRC-32, compressed length, bytes; None where
/// it is empty) and what follows it.
fn image<'a>(b: &'a [u8], dict: Option<&[u8]>) -> Result<(Option<Vec<u8>>, &'a [u8]), String> {
    let (len, b) = take(b, 8)?;
    let len = usize::try_from(u64::from_le_bytes(len.try_into().unwrap())).map_err(|_| "too long")?;
    let (crc, b) = take(b, 4)?;
    let (zlen, b) = take(b, 8)?;
    let zlen = usize::try_from(u64::from_le_bytes(zlen.try_into().unwrap())).map_err(|_| "too long")?;
    let (z, rest) = take(b, zlen)?;
    if len == 0 {
        return Ok((None, rest));
    }
    // A length past any kernel image is damage, not an allocation to make.
    if len > 64 << 20 {
        return Err("image length out of range".into());
    }
    let image = match dict {
        Some(d) => zstd::bulk::Decompressor::with_dictionary(d).and_then(|mut x| x.decompress(z, len)),
        None => zstd::bulk::decompress(z, len),
    }
    .map_err(|e| format!("image does not decompress: {e}"))?;
    if image.len() != len {
        return Err("image is shorter than its length".into());
    }
    if crc32fast::hash(&image) != u32::from_le_bytes(crc.try_into().unwrap()) {
        return Err("image fails its checksum".into());
    }
    Ok((Some(image), rest))
}

/// The entry of `bundle` with key `want` (None: there is none), or why the bundle cannot
/// be read.
pub(crate) fn read_entry(bundle: &[u8], want: u64) -> Result<Option<Entry>, String> {
    let (base, n, mut rest) = open(bundle)?;
    for _ in 0..n {
        let key = u64::from_le_bytes(take(rest, 8)?.0.try_into().unwrap());
        if key != want {
            rest = skip(rest)?;
            continue;
        }
        return parse(rest, base_image(base)?.as_deref()).map(|(e, _)| Some(e));
    }
    Ok(None)
}

/// The entry at the start of `b` (its key first) and what follows it.
fn parse<'a>(b: &'a [u8], base: Option<&[u8]>) -> Result<(Entry, &'a [u8]), String> {
    let (key, b) = take(b, 8)?;
    let (cc, b) = take(b, 4)?;
    let (n, b) = take(b, 4)?;
    let (arch, b) = take(b, u32::from_le_bytes(n.try_into().unwrap()) as usize)?;
    let arch = std::str::from_utf8(arch)
        .map_err(|_| "architecture is not text")?
        .to_string();
    let (image, rest) = image(b, Some(base.ok_or("an entry without a base image")?))?;
    let e = Entry {
        key: u64::from_le_bytes(key.try_into().unwrap()),
        cc: u32::from_le_bytes(cc.try_into().unwrap()),
        arch,
        image: image.ok_or("an empty image")?,
    };
    Ok((e, rest))
}

/// What follows the entry at the start of `b`, without decompressing it.
fn skip(b: &[u8]) -> Result<&[u8], String> {
    let (_, b) = take(b, 12)?;
    let (n, b) = take(b, 4)?;
    let (_, b) = take(b, u32::from_le_bytes(n.try_into().unwrap()) as usize + 12)?;
    let (zlen, b) = take(b, 8)?;
    let zlen = usize::try_from(u64::from_le_bytes(zlen.try_into().unwrap())).map_err(|_| "too long")?;
    Ok(take(b, zlen)?.1)
}

fn take(b: &[u8], n: usize) -> Result<(&[u8], &[u8]), String> {
    if b.len() < n {
        return Err("the bundle ends inside an entry".into());
    }
    Ok(b.split_at(n))
}

/// Compile the bundle's variants for `arch` with NVRTC (`soundloc cuda-prebuild`), on
/// every core (one NVRTC program per variant), saying on stderr how long each took.
pub(crate) fn build(arch: &str) -> Result<Vec<u8>, String> {
    let cc: u32 = arch
        .strip_prefix("sm_")
        .and_then(|c| c.parse().ok())
        .ok_or_else(|| format!("{arch}: expected sm_XY"))?;
    if !super::kernels::nvrtc_present() {
        return Err(
            "libnvrtc (the CUDA run-time compiler) was not found: pip install \
                    nvidia-cuda-nvrtc==13.0.88 and add its nvidia/cu13/lib folder to LD_LIBRARY_PATH"
                .into(),
        );
    }
    if std::env::var_os("SOUNDLOC_CUDA_NVRTC_OPTS").is_some() {
        return Err("SOUNDLOC_CUDA_NVRTC_OPTS is set: the bundle holds the default build only".into());
    }
    let vs = variants();
    let next = std::sync::atomic::AtomicUsize::new(0);
    let threads = std::thread::available_parallelism()
        .map_or(4, |n| n.get())
        .min(vs.len());
    let t0 = std::time::Instant::now();
    let mut done: Vec<(usize, Result<Entry, String>)> = std::thread::scope(|s| {
        let workers: Vec<_> = (0..threads)
            .map(|_| {
                s.spawn(|| {
                    let mut out = Vec::new();
                    loop {
                        let i = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                        let Some(&v) = vs.get(i) else { break out };
                        let src = full_source(v);
                        let opts = options(arch);
                        let t = std::time::Instant::now();
                        let r = super::kernels::nvrtc_compile(&src, &opts, true).map(|image| Entry {
                            key: key(&src, &opts, cc),
                            cc,
                            arch: arch.to_string(),
                            image,
                        });
                        eprintln!(
                            "soundloc: {} f32: {:.1} s (at {:.1} s)",
                            v.tag(),
                            t.elapsed().as_secs_f64(),
                            t0.elapsed().as_secs_f64()
                        );
                        out.push((i, r));
                    }
                })
            })
            .collect();
        workers
            .into_iter()
            .flat_map(|w| w.join().unwrap_or_default())
            .collect()
    });
    if done.len() != vs.len() {
        return Err("a compilation thread failed".into());
    }
    done.sort_by_key(|(i, _)| *i);
    let entries = done.into_iter().map(|(_, r)| r).collect::<Result<Vec<_>, _>>()?;
    write(&entries).map_err(|e| e.to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An entry whose image does not compress (a linear congruential sequence).
    fn entry(key: u64, seed: u64, len: usize) -> Entry {
        let mut x = seed;
        let image = (0..len)
            .map(|_| {
                x = x
                    .wrapping_mul(6_364_136_223_846_793_005)
                    .wrapping_add(1_442_695_040_888_963_407);
                (x >> 56) as u8
            })
            .collect();
        Entry {
            key,
            cc: 90,
            arch: "sm_90".into(),
            image,
        }
    }

    /// Entries come back as written, found by key; a damaged bundle is an error, never
    /// a wrong image.
    #[test]
    fn a_bundle_reads_back_and_damage_is_refused() {
        let es = [entry(1, 3, 1000), entry(7, 9, 50_000), entry(42, 0, 1)];
        let b = write(&es).unwrap();
        for e in &es {
            assert_eq!(read_entry(&b, e.key).unwrap().as_ref(), Some(e));
        }
        assert_eq!(read_entry(&b, 5).unwrap(), None);
        assert_eq!(read_entry(&write(&[]).unwrap(), 1).unwrap(), None);
        // Cut anywhere: an error or (cut after the entry sought) that entry intact.
        for cut in (0..b.len()).step_by(97) {
            match read_entry(&b[..cut], 42) {
                Ok(Some(e)) => assert_eq!(e, es[2]),
                Ok(None) => panic!("cut at {cut}: a miss, not an error"),
                Err(_) => {}
            }
        }
        // A flipped bit anywhere: an error, a miss (a key changed) or the right image,
        // never a wrong one (the checksum).
        for at in (MAGIC.len()..b.len()).step_by(31) {
            let mut bad = b.clone();
            bad[at] ^= 0x10;
            for e in &es {
                if let Ok(Some(got)) = read_entry(&bad, e.key) {
                    assert_eq!(got.image, e.image, "flip at {at}");
                }
            }
        }
        assert!(read_entry(b"SLCUDAIMG1\n", 1).is_err());
        // A bundle of similar images is much smaller than they are (the base as dictionary).
        let similar: Vec<Entry> = (0..4)
            .map(|k| {
                let mut e = entry(100 + k, 5, 200_000);
                e.image[1000 * k as usize] ^= 0xff;
                e
            })
            .collect();
        let b = write(&similar).unwrap();
        assert!(b.len() < 300_000, "{} bytes", b.len());
        for e in &similar {
            assert_eq!(read_entry(&b, e.key).unwrap().as_ref(), Some(e));
        }
    }

    /// Every embedded bundle holds an image for every variant it serves, compiled from
    /// the kernels as they are now: after a kernel edit, regenerate them
    /// (`scripts/cuda_prebuild.sh`, docs/gpu.md, "How to reproduce"; no GPU needed). A
    /// stale bundle would only cost the cold start (NVRTC compiles instead), which this
    /// test exists to keep.
    #[test]
    fn the_embedded_bundles_are_for_these_kernels() {
        for &(cc, bundle) in BUNDLES {
            let arch = format!("sm_{cc}");
            let have = embedded(bundle).unwrap();
            assert!(have.iter().all(|e| e.cc == cc && e.arch == arch), "{arch}");
            let keys: Vec<u64> = have.iter().map(|e| e.key).collect();
            for v in variants() {
                let k = key(&full_source(v), &options(&arch), cc);
                assert!(
                    keys.contains(&k),
                    "no prebuilt {arch} image for {} f32 with the current kernel sources: \
                     regenerate kernels/prebuilt/*.bin (scripts/cuda_prebuild.sh: docs/gpu.md, \
                     \"How to reproduce\")",
                    v.tag()
                );
            }
            assert_eq!(have.len(), variants().len(), "{arch}");
            // What a device of this very capability finds: an image of this bundle.
            let img = find(variants()[3], cc).unwrap();
            assert_eq!(img.arch, arch);
            assert!(img.prebuilt);
        }
    }

    /// A device takes the bundle of its major version with the highest minor version at
    /// or below its own; none for a major version without a bundle.
    #[test]
    fn a_device_takes_the_bundle_of_its_major_version() {
        let have: Vec<u32> = BUNDLES.iter().map(|b| b.0).collect();
        assert_eq!(have, [75, 80, 90, 100, 120]);
        for (cc, want) in [
            (75, Some(75)),
            (80, Some(80)),
            (86, Some(80)),
            (87, Some(80)),
            (89, Some(80)),
            (90, Some(90)),
            (100, Some(100)),
            (103, Some(100)),
            (110, None),
            (120, Some(120)),
            (121, Some(120)),
            (70, None),
            (61, None),
        ] {
            assert_eq!(bundle_for(cc, &have), want, "cc {cc}");
        }
        // A bundle above the device's minor version is not taken (8.0's images are not
        // for 7.x, an 8.6 bundle would not serve 8.0).
        assert_eq!(bundle_for(80, &[86]), None);
        assert_eq!(bundle_for(89, &[80, 86]), Some(86));
        let img = find(variants()[0], 89).unwrap();
        assert_eq!(img.arch, "sm_80");
        assert!(find(variants()[0], 70).is_none());
    }
}
