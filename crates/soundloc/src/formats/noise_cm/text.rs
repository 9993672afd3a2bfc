//! The HARK ≤ 2.0 text pair: reading and writing it, and the file-name rules that pair a
//! real-part file with its imaginary-part file (see the [parent module docs](super)).

use std::io::Write as _;
use std::path::{Path, PathBuf};

use num_complex::Complex;

use super::{check_bin, Expected, NoiseCm};
use crate::error::{Error, Result};
use crate::output::atomic::write_atomically;

impl NoiseCm {
    /// Reads a HARK ≤ 2.0 text pair (real-part file, imaginary-part file).
    pub fn read_text_pair(real: &Path, imag: &Path, expected: Expected) -> Result<Self> {
        let re = read_text_matrix(real, expected)?;
        let im = read_text_matrix(imag, expected)?;
        if re.rows.len() != im.rows.len() || re.cols != im.cols {
            return Err(Error::format(
                imag,
                format!(
                    "{} lines of {} numbers, but the real part {} has {} lines of {}",
                    im.rows.len(),
                    im.cols,
                    real.display(),
                    re.rows.len(),
                    re.cols
                ),
            ));
        }
        let m = re.num_mics;
        let data: Vec<Complex<f64>> = re
            .rows
            .iter()
            .zip(&im.rows)
            .flat_map(|(r, i)| r.iter().zip(i).map(|(&a, &b)| Complex::new(a, b)))
            .collect();
        let nfft = expected.nfft.unwrap_or(2 * (re.rows.len() - 1));
        let cm = NoiseCm {
            num_mics: m,
            nfft,
            data,
        };
        for k in 0..cm.num_bins() {
            check_bin(cm.get(k), m).map_err(|msg| {
                Error::format(
                    real,
                    format!("line {} (bin {k}, with {}): {msg}", k + 1, imag.display()),
                )
            })?;
        }
        Ok(cm)
    }

    /// Writes the HARK ≤ 2.0 text pair (each file atomically).
    pub fn write_text_pair(&self, real: &Path, imag: &Path) -> Result<()> {
        self.validate_shape(real)?;
        self.check_values(real)?;
        let part = |f: fn(&Complex<f64>) -> f64| {
            let mut s = String::new();
            for k in 0..self.num_bins() {
                for (c, z) in self.get(k).iter().enumerate() {
                    if c > 0 {
                        s.push(' ');
                    }
                    s.push_str(&format!("{:e}", f(z)));
                }
                s.push('\n');
            }
            s
        };
        let re = part(|z| z.re);
        write_atomically(real, |w| w.write_all(re.as_bytes()))?;
        let im = part(|z| z.im);
        write_atomically(imag, |w| w.write_all(im.as_bytes()))
    }
}

/// The two files of a text pair written for the output name `output`: (real, imaginary).
/// See the module docs for the rule.
pub fn text_pair_paths(output: &Path) -> (PathBuf, PathBuf) {
    let name = output
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let (stem, ext) = match name.rfind('.') {
        Some(i) if i > 0 => (&name[..i], &name[i..]),
        _ => (name.as_str(), ""),
    };
    let marks_real = name.ends_with(".real")
        || name.ends_with(".re")
        || ["real", "Real", "REAL", "_re", "-re", "_r", "-r", "_R", "-R"]
            .iter()
            .any(|m| stem.ends_with(m));
    if marks_real {
        if let Some(imag) = imag_path_candidates(output).into_iter().next() {
            return (output.to_path_buf(), imag);
        }
    }
    (
        output.with_file_name(format!("{stem}_r{ext}")),
        output.with_file_name(format!("{stem}_i{ext}")),
    )
}

struct TextMatrix {
    rows: Vec<Vec<f64>>,
    cols: usize,
    num_mics: usize,
}

/// Reads one text file of the pair: N/2 + 1 lines of M² finite numbers.
fn read_text_matrix(path: &Path, expected: Expected) -> Result<TextMatrix> {
    let text = crate::formats::read_text_bounded(
        path,
        crate::formats::MAX_NOISE_TEXT_BYTES,
        "noise correlation text file",
    )?;
    let mut rows = Vec::new();
    let mut cols = None;
    for (i, line) in text.lines().enumerate() {
        let n = i + 1;
        if line.trim().is_empty() {
            continue;
        }
        let mut row = Vec::new();
        for (c, tok) in line.split_whitespace().enumerate() {
            let v: f64 = tok.parse().map_err(|_| {
                Error::format(path, format!("line {n}, column {}: not a number: {tok:?}", c + 1))
            })?;
            if !v.is_finite() {
                return Err(Error::format(
                    path,
                    format!("line {n}, column {}: not finite: {tok:?}", c + 1),
                ));
            }
            row.push(v);
        }
        match cols {
            None => {
                let m = isqrt(row.len());
                if m * m != row.len() {
                    return Err(Error::format(
                        path,
                        format!(
                            "line {n}: {} numbers is not M² for any microphone count M",
                            row.len()
                        ),
                    ));
                }
                if let Some(em) = expected.num_mics {
                    if em != m {
                        return Err(Error::format(
                            path,
                            format!(
                                "line {n}: {} numbers = {m}² but {em} microphones expected ({} numbers)",
                                row.len(),
                                em * em
                            ),
                        ));
                    }
                }
                cols = Some(row.len());
            }
            Some(c) if c != row.len() => {
                return Err(Error::format(
                    path,
                    format!("line {n}: {} numbers, expected {c} like line 1", row.len()),
                ));
            }
            Some(_) => {}
        }
        rows.push(row);
    }
    let Some(cols) = cols else {
        return Err(Error::format(path, "empty file: no matrix lines"));
    };
    match expected.nfft {
        Some(nfft) if rows.len() != nfft / 2 + 1 => {
            return Err(Error::format(
                path,
                format!(
                    "{} lines, expected {} (one per bin: nfft {nfft} → nfft/2+1)",
                    rows.len(),
                    nfft / 2 + 1
                ),
            ))
        }
        None if rows.len() < 2 => {
            return Err(Error::format(
                path,
                format!("{} line(s): need nfft/2+1 ≥ 2 lines, one per bin", rows.len()),
            ))
        }
        _ => {}
    }
    Ok(TextMatrix {
        rows,
        cols,
        num_mics: isqrt(cols),
    })
}

fn isqrt(n: usize) -> usize {
    let mut r = (n as f64).sqrt() as usize;
    while r * r > n {
        r -= 1;
    }
    while (r + 1) * (r + 1) <= n {
        r += 1;
    }
    r
}

/// Candidate imaginary-part paths for a real-part path, in the order tried (see the module
/// docs for the renaming rules).
pub fn imag_path_candidates(real: &Path) -> Vec<PathBuf> {
    let Some(name) = real.file_name().and_then(|n| n.to_str()) else {
        return Vec::new();
    };
    let mut names: Vec<String> = Vec::new();
    for (from, to) in [(".real", ".imag"), (".re", ".im")] {
        if let Some(base) = name.strip_suffix(from) {
            names.push(format!("{base}{to}"));
        }
    }
    let (stem, ext) = match name.rfind('.') {
        Some(i) if i > 0 => (&name[..i], &name[i..]),
        _ => (name, ""),
    };
    for (from, to) in [
        ("real", "imag"),
        ("Real", "Imag"),
        ("REAL", "IMAG"),
        ("_re", "_im"),
        ("-re", "-im"),
        ("r", "i"),
        ("R", "I"),
    ] {
        if let Some(base) = stem.strip_suffix(from) {
            names.push(format!("{base}{to}{ext}"));
        }
    }
    let mut seen = std::collections::HashSet::new();
    names
        .into_iter()
        .filter(|n| n != name && seen.insert(n.clone()))
        .map(|n| real.with_file_name(n))
        .collect()
}

/// The imaginary-part file of a text pair: the first existing [`imag_path_candidates`].
pub fn find_imag_path(real: &Path) -> Result<PathBuf> {
    let cands = imag_path_candidates(real);
    if let Some(p) = cands.iter().find(|p| p.is_file()) {
        return Ok(p.clone());
    }
    let tried: Vec<String> = cands.iter().map(|p| p.display().to_string()).collect();
    Err(Error::format(
        real,
        if tried.is_empty() {
            "cannot derive the imaginary-part file name (expected names like X_r.dat/X_i.dat, X.real/X.imag); give both as REAL,IMAG".to_string()
        } else {
            format!(
                "imaginary-part file not found (tried {}); give both as REAL,IMAG",
                tried.join(", ")
            )
        },
    ))
}

#[cfg(test)]
mod tests {
    use super::super::tests::hermitian;
    use super::*;

    #[test]
    fn text_pair_names_are_found_again() {
        let cases = [
            ("K", "K_r", "K_i"),
            ("noise.dat", "noise_r.dat", "noise_i.dat"),
            ("noise_r.dat", "noise_r.dat", "noise_i.dat"),
            ("cm.real", "cm.real", "cm.imag"),
            ("cm_real.txt", "cm_real.txt", "cm_imag.txt"),
            ("cluster", "cluster_r", "cluster_i"),
        ];
        let dir = std::env::temp_dir().join(format!("soundloc-cmnames-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let cm = hermitian(2, 8, 3);
        for (out, re, im) in cases {
            let (r, i) = text_pair_paths(&dir.join(out));
            assert_eq!((r.clone(), i.clone()), (dir.join(re), dir.join(im)), "{out}");
            cm.write_text_pair(&r, &i).unwrap();
            assert_eq!(find_imag_path(&r).unwrap(), i, "{out}");
            let back = NoiseCm::load(&r, Expected::default()).unwrap();
            assert_eq!(back, cm);
            // By the name it was written for, too, when no file has that name.
            if !dir.join(out).exists() {
                assert_eq!(
                    NoiseCm::load(&dir.join(out), Expected::default()).unwrap(),
                    cm,
                    "{out}"
                );
            }
        }
        let _ = std::fs::remove_dir_all(&dir);
    }
}
