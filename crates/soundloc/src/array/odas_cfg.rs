//! An ODAS configuration file as an array description (`odaslive -c respeaker.cfg`).
//!
//! ODAS users describe their array in libconfig ([`crate::formats::libconfig`]); soundloc
//! reads from it what describes the array:
//! - `general.mics[i].mu = (x, y, z)`: microphone i's position in metres, in ODAS's frame
//!   (x, y, z right-handed, as soundloc's: azimuth = atan2(y, x));
//! - `raw.nChannels` and `mapping.map = (c₁, …)`: the capture device's channel count and,
//!   1-based, the device channel of each microphone (a ReSpeaker USB array delivers 6
//!   channels, its 4 microphones on 2–5). They become a [`RawMapping`] (0-based).
//!
//! The rest (ODAS's sample rate, speed of sound, noise, SSL/SST and sink settings) drives
//! ODAS's own processing and is not used: soundloc takes the input's sampling rate and its
//! own options.

use super::Geometry;
use crate::formats::libconfig::{self, Value};
use crate::input::RawMapping;
use crate::{Error, Result};
use std::path::Path;

/// The array an ODAS configuration describes.
#[derive(Debug, Clone, PartialEq)]
pub struct OdasArray {
    /// Microphone positions, in the file's (and `mapping.map`'s) order.
    pub geometry: Geometry,
    /// The device's channel layout, when the file has a `mapping` section.
    pub mapping: Option<RawMapping>,
}

impl OdasArray {
    /// Read an ODAS configuration file.
    pub fn load(path: &Path) -> Result<Self> {
        let text = crate::formats::read_text_bounded(
            path,
            crate::formats::MAX_GEOMETRY_BYTES,
            "configuration file",
        )?;
        Self::from_str(&text, path)
    }

    /// Parse the libconfig text of an ODAS configuration; errors name `path`.
    pub fn from_str(text: &str, path: &Path) -> Result<Self> {
        let root = libconfig::parse(text, path)?;
        let fail = |m: String| Error::format(path, m);
        let mics = root
            .get("general")
            .and_then(|g| g.get("mics"))
            .ok_or_else(|| fail("no `general.mics` list: not an ODAS array configuration".into()))?
            .as_list()
            .ok_or_else(|| fail("`general.mics` must be a list of { mu = (x, y, z); } groups".into()))?;
        let mut positions = Vec::with_capacity(mics.len());
        for (i, m) in mics.iter().enumerate() {
            let mu = m.get("mu").ok_or_else(|| {
                fail(format!(
                    "general.mics[{i}]: no `mu` (its position x, y, z in metres)"
                ))
            })?;
            let coords = mu.as_list().filter(|c| c.len() == 3).ok_or_else(|| {
                fail(format!(
                    "general.mics[{i}].mu: expected (x, y, z), found {}",
                    describe(mu)
                ))
            })?;
            let mut p = [0.0; 3];
            for (k, c) in coords.iter().enumerate() {
                p[k] = c.as_f64().ok_or_else(|| {
                    fail(format!(
                        "general.mics[{i}].mu: coordinate {k} is {}, not a number",
                        c.kind()
                    ))
                })?;
            }
            positions.push(p);
        }
        let geometry = Geometry::new(positions, path)?;
        let mapping = match root.get("mapping").map(|m| m.get("map")) {
            None => None,
            Some(None) => return Err(fail("the `mapping` section has no `map`".into())),
            Some(Some(map)) => Some(device_map(&root, map, geometry.num_mics(), path)?),
        };
        Ok(OdasArray { geometry, mapping })
    }
}

/// `mapping.map` (1-based device channels) with `raw.nChannels`, checked, 0-based.
fn device_map(root: &Value, map: &Value, mics: usize, path: &Path) -> Result<RawMapping> {
    let fail = |m: String| Error::format(path, m);
    let channels = root
        .get("raw")
        .and_then(|r| r.get("nChannels"))
        .ok_or_else(|| fail("`mapping.map` needs `raw.nChannels` (the device's channel count)".into()))?;
    let channels = channels
        .as_i64()
        .filter(|&n| (1..=crate::array::MAX_MICS as i64 * 4).contains(&n))
        .ok_or_else(|| {
            fail(format!(
                "raw.nChannels must be a positive channel count, found {}",
                describe(channels)
            ))
        })? as usize;
    let list = map.as_list().ok_or_else(|| {
        fail(format!(
            "mapping.map must be a list of channels, found {}",
            map.kind()
        ))
    })?;
    let mut out = Vec::with_capacity(list.len());
    for (i, c) in list.iter().enumerate() {
        match c.as_i64() {
            Some(c) if c >= 1 && c as u64 <= channels as u64 => out.push(c as usize - 1),
            _ => {
                return Err(fail(format!(
                    "mapping.map[{i}] is {}: channels are numbered 1..={channels} (raw.nChannels)",
                    describe(c)
                )))
            }
        }
    }
    if out.len() != mics {
        return Err(fail(format!(
            "mapping.map lists {} channels but general.mics has {mics} microphones",
            out.len()
        )));
    }
    if let Some((c, first, again)) = crate::input::repeated(&out) {
        return Err(fail(format!(
            "mapping.map: channel {} feeds microphones {} and {} (each channel one microphone)",
            c + 1,
            first + 1,
            again + 1
        )));
    }
    Ok(RawMapping { channels, map: out })
}

fn describe(v: &Value) -> String {
    match v {
        Value::Int(i) => i.to_string(),
        Value::Float(f) => format!("{f:?}"),
        Value::List(l) => format!("a list of {}", l.len()),
        v => v.kind().to_string(),
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// ODAS's own file for the ReSpeaker USB 4 Mic Array (config/odaslive/
    /// respeaker_usb_4_mic_array.cfg in introlab/odas), its array sections verbatim.
    pub(crate) const RESPEAKER_USB: &str = r#"
# Configuration file for ReSpeaker USB 4 Mic Array (ReSpeaker USB Mic Array v2.0)

version = "2.1";

# Raw

raw: 
{

    fS = 16000;
    hopSize = 128;
    nBits = 16;
    nChannels = 6; 

    # Input with raw signal from microphones
    interface: {
        type = "soundcard";
        card = 1;
        device = 0;
    }

}

# Mapping

mapping:
{

    map: (2, 3, 4, 5);

}

# General

general:
{
    
    epsilon = 1E-20;

    size: 
    {
        hopSize = 128;
        frameSize = 256;
    };
    
    samplerate:
    {
        mu = 16000;
        sigma2 = 0.01;
    };

    speedofsound:
    {
        mu = 343.0;
        sigma2 = 25.0;
    };

    mics = (

        # Microphone 2
        { 
            mu = ( -0.032, +0.000, +0.000 ); 
            sigma2 = ( +0.000, +0.000, +0.000, +0.000, +0.000, +0.000, +0.000, +0.000, +0.000 );
            direction = ( +0.000, +0.000, +1.000 );
            angle = ( 80.0, 100.0 );
        },

        # Microphone 3
        { 
            mu = ( +0.000, -0.032, +0.000 ); 
            sigma2 = ( +0.000, +0.000, +0.000, +0.000, +0.000, +0.000, +0.000, +0.000, +0.000 );
            direction = ( +0.000, +0.000, +1.000 );
            angle = ( 80.0, 100.0 );
        },

        # Microphone 4
        { 
            mu = ( +0.032, +0.000, +0.000 ); 
            sigma2 = ( +0.000, +0.000, +0.000, +0.000, +0.000, +0.000, +0.000, +0.000, +0.000 );
            direction = ( +0.000, +0.000, +1.000 );
            angle = ( 80.0, 100.0 );
        },

        # Microphone 5
        { 
            mu = ( +0.000, +0.032, +0.000 ); 
            sigma2 = ( +0.000, +0.000, +0.000, +0.000, +0.000, +0.000, +0.000, +0.000, +0.000 );
            direction = ( +0.000, +0.000, +1.000 );
            angle = ( 80.0, 100.0 );        
        }
        
    );

    # Spatial filter to include only a range of direction if required
    # (may be useful to remove false detections from the floor)
    spatialfilters = (

        {
            direction = ( +0.000, +0.000, +1.000 );
            angle = (80.0, 100.0);

        }    

    );

    nThetas = 181;
    gainMin = 0.25;

};

# Stationnary noise estimation

sne:
{
    
    b = 3;
    alphaS = 0.1;
    L = 150;
    delta = 3.0;
    alphaD = 0.1;

};
"#;

    #[test]
    fn reads_odas_own_respeaker_file() {
        let a = OdasArray::from_str(RESPEAKER_USB, Path::new("respeaker.cfg")).unwrap();
        assert_eq!(
            a.geometry.mics,
            vec![
                [-0.032, 0.0, 0.0],
                [0.0, -0.032, 0.0],
                [0.032, 0.0, 0.0],
                [0.0, 0.032, 0.0]
            ]
        );
        assert_eq!(
            a.mapping,
            Some(RawMapping {
                channels: 6,
                map: vec![1, 2, 3, 4]
            })
        );
        // Without a mapping section: positions only.
        let cut = RESPEAKER_USB
            .replace("map: (2, 3, 4, 5);", "")
            .replace("mapping:", "unused:");
        assert_eq!(
            OdasArray::from_str(&cut, Path::new("r.cfg")).unwrap().mapping,
            None
        );
    }

    #[test]
    fn errors_name_the_file_and_the_setting() {
        let e = |from: &str, to: &str| {
            let t = RESPEAKER_USB.replacen(from, to, 1);
            assert_ne!(t, RESPEAKER_USB, "{from}");
            OdasArray::from_str(&t, Path::new("r.cfg"))
                .unwrap_err()
                .to_string()
        };
        assert_eq!(
            e("map: (2, 3, 4, 5)", "map: (2, 3, 4, 7)"),
            "r.cfg: mapping.map[3] is 7: channels are numbered 1..=6 (raw.nChannels)"
        );
        assert_eq!(
            e("map: (2, 3, 4, 5)", "map: (2, 3, 4)"),
            "r.cfg: mapping.map lists 3 channels but general.mics has 4 microphones"
        );
        assert!(e("map: (2, 3, 4, 5)", "map: (2, 3, 3, 5)")
            .contains("mapping.map: channel 3 feeds microphones 2 and 3"));
        assert!(e("nChannels = 6;", "").contains("needs `raw.nChannels`"));
        assert_eq!(
            e("mu = ( +0.032, +0.000, +0.000 )", "mu = ( +0.032, +0.000 )"),
            "r.cfg: general.mics[2].mu: expected (x, y, z), found a list of 2"
        );
        assert!(e(
            "mu = ( +0.000, +0.032, +0.000 )",
            "mu = ( +0.000, -0.032, +0.000 )"
        )
        .contains("same position as mic 1"));
        assert!(e("mu = ( -0.032,", "mu = ( \"a\",").contains("general.mics[0].mu: coordinate 0 is a string"));
        assert!(e("mics = (", "mikes = (").contains("no `general.mics` list"));
        let syntax = e("nChannels = 6;", "nChannels = 6 6;");
        assert!(
            syntax.starts_with("r.cfg: line 14: expected a setting name"),
            "{syntax}"
        );
    }
}
