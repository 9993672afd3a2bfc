//! The HARK ≥ 2.1 correlation-matrix zip: reading and writing it (see the
//! [parent module docs](super) for the layout).

use std::collections::BTreeMap;
use std::path::Path;

use num_complex::Complex;

use super::{check_bin, Expected, NoiseCm, CM_ROOT};
use crate::error::{Error, Result};
use crate::formats::hark_mat::{read_mat, write_mat, MatData};
use crate::formats::{hark_zip, xml};

impl NoiseCm {
    /// Reads a HARK ≥ 2.1 correlation-matrix zip (see the module docs).
    pub fn read_zip(path: &Path, expected: Expected) -> Result<Self> {
        let entries = hark_zip::read_zip_entries(path)?;
        let (root, what) = hark_zip::container_root(&entries, path)?;
        if what != hark_zip::CM_WHATISTHIS {
            return Err(Error::format(
                hark_zip::entry_path(path, &format!("{root}whatisthis.txt")),
                format!(
                    "says {what:?}, expected {:?} (a transfer-function zip is not a noise matrix)",
                    hark_zip::CM_WHATISTHIS
                ),
            ));
        }
        // Matrices: `<root>…/<letters><digits>.mat`, grouped by folder.
        let mut folders: BTreeMap<&str, BTreeMap<usize, &String>> = BTreeMap::new();
        for name in entries.keys() {
            let Some(rel) = name.strip_prefix(root.as_str()) else {
                continue;
            };
            let Some(stem) = rel.strip_suffix(".mat") else {
                continue;
            };
            let (dir, file) = match stem.rfind('/') {
                Some(i) => (&rel[..i], &stem[i + 1..]),
                None => ("", stem),
            };
            let digits = file.trim_start_matches(|c: char| !c.is_ascii_digit());
            if digits.is_empty() || !digits.bytes().all(|b| b.is_ascii_digit()) {
                continue;
            }
            if let Ok(bin) = digits.parse::<usize>() {
                folders.entry(dir).or_default().insert(bin, name);
            }
        }
        let chosen = folders
            .iter()
            .find(|(d, _)| d.rsplit('/').next() == Some("localization"))
            .or_else(|| folders.iter().next())
            .map(|(_, m)| m)
            .ok_or_else(|| Error::format(path, format!("no <bin>.mat matrices under {root:?}")))?;
        let num_bins = chosen.len();
        for (i, (&bin, name)) in chosen.iter().enumerate() {
            if bin != i {
                return Err(Error::format(
                    path,
                    format!("bin {i} is missing (next matrix: {name}); bins must be numbered 0..{num_bins}"),
                ));
            }
        }
        // nfft: from any <nfft> in an XML file of the container, else from the bin count.
        let mut nfft = None;
        for (name, bytes) in entries.range(root.clone()..) {
            if !name.starts_with(root.as_str()) {
                break;
            }
            if name.ends_with(".xml") {
                let ep = hark_zip::entry_path(path, name);
                let doc = xml::parse_file_text(&String::from_utf8_lossy(bytes), &ep)?;
                if let Some(e) = doc.find("nfft") {
                    let t = e.text_trimmed();
                    nfft = Some(t.parse::<usize>().map_err(|_| {
                        Error::format(&ep, format!("<nfft> is not a positive integer: {t:?}"))
                    })?);
                    break;
                }
            }
        }
        let nfft = match nfft {
            Some(n) if n / 2 + 1 != num_bins => {
                return Err(Error::format(
                    path,
                    format!("{num_bins} matrices, but nfft {n} needs nfft/2+1 = {}", n / 2 + 1),
                ))
            }
            Some(n) => n,
            None if num_bins < 2 => {
                return Err(Error::format(
                    path,
                    format!("{num_bins} matrix: need nfft/2+1 ≥ 2"),
                ))
            }
            None => 2 * (num_bins - 1),
        };
        let mut m = 0;
        let mut data = Vec::new();
        for (&bin, name) in chosen {
            let ep = hark_zip::entry_path(path, name);
            let mat = read_mat(&entries[*name], &ep)?;
            let (rows, cols) = (mat.rows, mat.cols);
            if rows != cols || rows == 0 {
                return Err(Error::format(
                    &ep,
                    format!("{rows} × {cols} matrix, expected M × M"),
                ));
            }
            if bin == 0 {
                m = rows;
            } else if rows != m {
                return Err(Error::format(
                    &ep,
                    format!("{rows} × {rows} matrix, but bin 0 is {m} × {m}"),
                ));
            }
            if let Some(em) = expected.num_mics {
                if em != m {
                    return Err(Error::format(
                        &ep,
                        format!("{m} × {m} matrix, expected {em} microphones"),
                    ));
                }
            }
            let vals = mat.into_complex(&ep)?;
            if vals.len() != m * m {
                return Err(Error::format(
                    &ep,
                    format!("{} values, expected {}", vals.len(), m * m),
                ));
            }
            let start = data.len();
            data.extend(
                vals.iter()
                    .map(|z| Complex::new(f64::from(z.re), f64::from(z.im))),
            );
            check_bin(&data[start..], m).map_err(|msg| Error::format(&ep, format!("bin {bin}: {msg}")))?;
        }
        let cm = NoiseCm {
            num_mics: m,
            nfft,
            data,
        };
        cm.check_expected(expected, path)?;
        Ok(cm)
    }

    /// The zip's entries (see the module docs), in writing order.
    pub fn zip_entries(&self) -> Result<Vec<(String, Vec<u8>)>> {
        self.validate_shape(Path::new(CM_ROOT))?;
        let root = format!("{CM_ROOT}/");
        let m = self.num_mics;
        let mut e: Vec<(String, Vec<u8>)> = vec![
            (root.clone(), Vec::new()),
            (
                format!("{root}whatisthis.txt"),
                hark_zip::CM_WHATISTHIS.as_bytes().to_vec(),
            ),
        ];
        let mics = hark_zip::positions_element("microphone", &vec![[0.0; 3]; m], None);
        e.push((
            format!("{root}microphones.xml"),
            hark_zip::hark_xml_document(vec![mics], false).into_bytes(),
        ));
        let config = xml::Element::new("config")
            .with_child(xml::Element::new("nfft").with_text(self.nfft.to_string()));
        let bins = hark_zip::positions_element("frequency", &vec![[0.0; 3]; self.num_bins()], None);
        e.push((
            format!("{root}source.xml"),
            hark_zip::hark_xml_document(vec![config, bins], false).into_bytes(),
        ));
        e.push((format!("{root}localization/"), Vec::new()));
        for k in 0..self.num_bins() {
            let vals = self
                .get(k)
                .iter()
                .map(|z| Complex::new(z.re as f32, z.im as f32))
                .collect();
            e.push((
                format!("{root}localization/cm{k:05}.mat"),
                write_mat(&MatData::complex(m, m, vals)),
            ));
        }
        Ok(e)
    }

    /// Writes the HARK ≥ 2.1 zip (atomically; values rounded to f32).
    pub fn write_zip(&self, path: &Path) -> Result<()> {
        self.validate_shape(path)?;
        self.check_values(path)?;
        // The zip holds f32: a value beyond its range would be read back as infinite.
        let big = |v: f64| v.abs() > f32::MAX as f64;
        if let Some(i) = self.data.iter().position(|z| big(z.re) || big(z.im)) {
            let mm = self.num_mics * self.num_mics;
            return Err(Error::Config(format!(
                "{}: K at bin {}, entry ({}, {}) = {} is beyond single precision (the zip holds f32): write the text pair",
                path.display(),
                i / mm,
                (i % mm) / self.num_mics,
                i % self.num_mics,
                self.data[i]
            )));
        }
        hark_zip::write_zip_entries(path, &self.zip_entries()?)
    }
}
