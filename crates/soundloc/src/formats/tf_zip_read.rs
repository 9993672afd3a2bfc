//! Reading HARK transfer-function zips (layout: [`super::hark_zip`]): the structure
//! (`whatisthis.txt`, `source.xml`, `microphones.xml`, which matrices exist) first, then
//! the localization matrices — only the bins asked for, inflated in parallel — or, to
//! describe a file quickly, only the first one.

use super::hark_mat::read_mat;
use super::hark_zip::{
    container_root, entry_path, entry_text, read_neighbors, read_positions, tf_entry_name, HarkConfig,
    TF_WHATISTHIS,
};
use super::xml;
use super::zip_archive::ZipReader;
use crate::array::transfer::TfSummary;
use crate::array::{Grid, TransferFunctions};
use crate::{Error, Result};
use num_complex::Complex;
use rayon::prelude::*;
use std::collections::BTreeMap;
use std::ops::Range;
use std::path::Path;

/// What the small entries of a TF zip say, and its open archive.
struct Head {
    zr: ZipReader,
    cfg: HarkConfig,
    grid: Grid,
    mic_positions: Vec<[f64; 3]>,
    mic_name: String,
    /// Localization matrix entry of each direction (all present).
    names: Vec<String>,
}

/// The settings (FFT length, sampling rate) a TF zip was made for, from its small entries
/// alone (no matrix is inflated): what `--resample` needs before choosing the bins to read.
pub fn read_tf_zip_config(path: &Path) -> Result<HarkConfig> {
    let (_, _, _, _, cfg) = read_small(path)?;
    Ok(cfg)
}

/// The open archive, its small entries, the container root, source.xml (parsed) and the
/// config it holds.
type Small = (
    ZipReader,
    BTreeMap<String, Vec<u8>>,
    String,
    xml::Element,
    HarkConfig,
);

/// [`Small`] of the zip at `path`.
fn read_small(path: &Path) -> Result<Small> {
    let mut zr = ZipReader::open(path)?;
    let small_names: Vec<String> = zr
        .names()
        .into_iter()
        .filter(|n| {
            let leaf = n.rsplit('/').next().unwrap_or("");
            matches!(leaf, "whatisthis.txt" | "source.xml" | "microphones.xml")
                && !n.contains("/localization/")
                && !n.contains("/separation/")
        })
        .collect();
    zr.check_total(small_names.iter().map(String::as_str))?;
    let mut entries = BTreeMap::new();
    for n in small_names {
        let b = zr.read(&n)?;
        entries.insert(n, b);
    }
    let (root, what) = container_root(&entries, path)?;
    if what != TF_WHATISTHIS {
        return Err(Error::format(
            entry_path(path, &format!("{root}whatisthis.txt")),
            format!("says {what:?}, expected {TF_WHATISTHIS:?}: not a transfer-function zip"),
        ));
    }
    let src_name = format!("{root}source.xml");
    let src_path = entry_path(path, &src_name);
    let src = xml::parse_file_text(&entry_text(&entries, &src_name, path)?, &src_path)?;
    let cfg = HarkConfig::from_xml(&src, &src_path)?;
    Ok((zr, entries, root, src, cfg))
}

fn read_head(path: &Path) -> Result<Head> {
    let (zr, entries, root, src, cfg) = read_small(path)?;
    let src_path = entry_path(path, &format!("{root}source.xml"));
    let points = read_positions(&src, "soundsource", &src_path)?
        .ok_or_else(|| Error::format(&src_path, "no <positions type=\"soundsource\">"))?;
    if points.is_empty() {
        return Err(Error::format(&src_path, "no source positions"));
    }
    let d = points.len();
    let neighbors = read_neighbors(&src, d, &src_path)?;
    let grid = match neighbors {
        Some(nb) => Grid::from_table(points, nb),
        None => Grid::from_points(points),
    }
    .map_err(|e| Error::format(&src_path, e.to_string()))?;

    let mic_name = format!("{root}microphones.xml");
    let mic_positions = match entries.get(&mic_name) {
        Some(b) => {
            let mp = entry_path(path, &mic_name);
            let doc = xml::parse_file_text(&String::from_utf8_lossy(b), &mp)?;
            read_positions(&doc, "microphone", &mp)?
                .or(read_positions(&doc, "", &mp)?)
                .unwrap_or_default()
        }
        None => Vec::new(),
    };

    let d = grid.len();
    let names: Vec<String> = (0..d)
        .map(|id| tf_entry_name(&root, "localization", id))
        .collect();
    for (id, name) in names.iter().enumerate() {
        if !zr.contains(name) {
            return Err(Error::format(
                path,
                format!("missing entry {name} (direction {id} of {d})"),
            ));
        }
    }
    Ok(Head {
        zr,
        cfg,
        grid,
        mic_positions,
        mic_name,
        names,
    })
}

/// Read a HARK transfer-function zip (see [`super::hark_zip`]), all bins.
pub fn read_tf_zip(path: &Path) -> Result<TransferFunctions> {
    read_tf_zip_bins(path, |_| None)
}

/// Describe a TF zip from its structure and its first matrix (every other matrix is
/// checked to exist but not inflated): what `soundloc tf inspect` prints, in a fraction of
/// the time a full read takes. [`read_tf_zip`] checks every matrix.
pub fn inspect_tf_zip(path: &Path) -> Result<TfSummary> {
    let mut h = read_head(path)?;
    let nbins = h.cfg.nfft / 2 + 1;
    let ep = entry_path(path, &h.names[0]);
    let bytes = h.zr.read(&h.names[0])?;
    let m = read_mat(&bytes, &ep)?;
    if m.rows == 0 || m.cols != nbins {
        return Err(Error::format(
            &ep,
            format!(
                "expected a matrix of microphones × {nbins} bins (nfft {}), found {} × {}",
                h.cfg.nfft, m.rows, m.cols
            ),
        ));
    }
    check_mics(path, &h, m.rows)?;
    Ok(TfSummary::new(
        &h.grid,
        h.cfg.nfft,
        h.cfg.sampling_rate_hz,
        m.rows,
        0..nbins,
        &h.mic_positions,
    ))
}

fn check_mics(path: &Path, h: &Head, num_mics: usize) -> Result<()> {
    if !h.mic_positions.is_empty() && h.mic_positions.len() != num_mics {
        return Err(Error::format(
            entry_path(path, &h.mic_name),
            format!(
                "lists {} microphones, but the TFs have {num_mics}",
                h.mic_positions.len()
            ),
        ));
    }
    Ok(())
}

/// Read a HARK transfer-function zip keeping only the bins `bins` picks from its
/// `<config>` (None, an empty range or one past N/2 + 1: all bins). Only the small XML
/// entries and the localization matrices are inflated (never the separation half), in
/// parallel (rayon; each worker inflates into its own buffer and keeps the picked bins),
/// so memory stays near the size of what is kept.
pub fn read_tf_zip_bins(
    path: &Path,
    bins: impl Fn(&HarkConfig) -> Option<Range<usize>>,
) -> Result<TransferFunctions> {
    let Head {
        mut zr,
        cfg,
        grid,
        mic_positions,
        mic_name,
        names,
    } = read_head(path)?;
    let d = grid.len();
    let nbins = cfg.nfft / 2 + 1;
    let keep = bins(&cfg)
        .filter(|r| !r.is_empty() && r.end <= nbins)
        .unwrap_or(0..nbins);
    zr.check_total(names.iter().map(String::as_str))?;
    // One direction's matrix: checked, the kept bins copied into `dst` (None: count rows).
    let read_one = |z: &mut ZipReader,
                    buf: &mut Vec<u8>,
                    id: usize,
                    rows: Option<usize>,
                    dst: &mut [Complex<f32>]|
     -> Result<usize> {
        let ep = entry_path(path, &names[id]);
        z.read_into(&names[id], buf)?;
        let m = read_mat(buf, &ep)?;
        let want_rows = rows.unwrap_or(m.rows);
        if want_rows == 0 {
            return Err(Error::format(&ep, "0 microphones (rows)"));
        }
        if m.rows != want_rows || m.cols != nbins {
            return Err(Error::format(
                &ep,
                format!(
                    "expected a {want_rows} × {nbins} matrix (microphones × nfft/2+1 with nfft {}), found {} × {}",
                    cfg.nfft, m.rows, m.cols
                ),
            ));
        }
        let v = m.into_complex(&ep)?;
        if let Some(k) = v.iter().position(|c| !(c.re.is_finite() && c.im.is_finite())) {
            return Err(Error::format(
                &ep,
                format!(
                    "non-finite value {} at mic {}, bin {}",
                    v[k],
                    k / nbins,
                    k % nbins
                ),
            ));
        }
        let nk = keep.len();
        for (r, out) in dst.chunks_mut(nk).enumerate().take(want_rows) {
            out.copy_from_slice(&v[r * nbins + keep.start..r * nbins + keep.end]);
        }
        Ok(want_rows)
    };
    // Direction 0 gives the microphone count; the data is sized by a matrix that was
    // read, not by a header's claim.
    let mut buf = Vec::new();
    let num_mics = read_one(&mut zr, &mut buf, 0, None, &mut [])?;
    let per_dir = num_mics * keep.len();
    let total = d.checked_mul(per_dir).filter(|&n| n <= 1 << 28).ok_or_else(|| {
        Error::format(
            path,
            format!(
                "{d} directions × {num_mics} mics × {} bins is too large",
                keep.len()
            ),
        )
    })?;
    let mut data = vec![Complex::new(0.0f32, 0.0); total];
    data.par_chunks_mut(per_dir).enumerate().try_for_each_init(
        || (zr.clone(), Vec::new()),
        |(z, buf), (id, dst)| read_one(z, buf, id, Some(num_mics), dst).map(|_| ()),
    )?;
    if !mic_positions.is_empty() && mic_positions.len() != num_mics {
        return Err(Error::format(
            entry_path(path, &mic_name),
            format!(
                "lists {} microphones, but the TFs have {num_mics}",
                mic_positions.len()
            ),
        ));
    }
    Ok(TransferFunctions {
        nfft: cfg.nfft,
        sample_rate_hz: cfg.sampling_rate_hz,
        grid,
        mic_positions,
        num_mics,
        first_bin: keep.start,
        num_bins: keep.len(),
        data,
    })
}
