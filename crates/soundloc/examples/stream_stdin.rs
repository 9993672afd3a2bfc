//! Localize 8-channel s16le PCM from standard input with a HARK transfer-function file,
//! printing each result as soon as its window is complete:
//!
//! ```sh
//! arecord -c 8 -r 16000 -f S16_LE -t raw | cargo run --release --example stream_stdin -- tf.zip
//! ```

use soundloc::{Block, Localizer, LocalizerSpec, NoiseSource, Output, WindowType};
use std::io::Read;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let tf = std::env::args()
        .nth(1)
        .ok_or("usage: stream_stdin TF.zip < pcm")?;
    let mut spec = LocalizerSpec::from_tf(tf); // every option is a field (serde)
    spec.analysis.window_type = WindowType::Past; // causal: a result as soon as its frame is in
    spec.analysis.period = 10;
    spec.noise = NoiseSource::Range {
        start_s: 0.0,
        end_s: 1.0,
    }; // K from the first second: GEVD
    let mut loc = Localizer::new(&spec)?;
    for n in loc.notes() {
        eprintln!("{n}");
    }
    let channels = loc.num_mics();
    let mut out = Output::default();
    let mut stdin = std::io::stdin().lock();
    let mut bytes = vec![0u8; 160 * channels * 2]; // 10 ms
    while stdin.read_exact(&mut bytes).is_ok() {
        let block: Vec<f32> = bytes
            .chunks_exact(2)
            .map(|b| i16::from_le_bytes([b[0], b[1]]) as f32)
            .collect();
        loc.push(
            Block::Interleaved {
                data: &block,
                channels,
            },
            &mut out,
        )?;
        for r in out.results.drain(..) {
            let s: Vec<String> = r
                .sources
                .iter()
                .map(|s| format!("{:.0}°", s.azimuth_deg))
                .collect();
            println!("{:7.2} s  {}", r.time_s, s.join("  "));
        }
    }
    loc.flush(&mut out)?;
    for r in out.results.drain(..) {
        println!("{:7.2} s  {} sources", r.time_s, r.sources.len());
    }
    Ok(())
}
