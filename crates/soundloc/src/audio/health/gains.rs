//! The gains check: channels whose level departs from what the transfer functions expect.
//!
//! A far sound field reaches every microphone of a small array at about the level the
//! transfer functions give it, so over a recording channel m's power in the used bins,
//! P_m = Σ |X_{m,k}|² over the STFT frames and used bins k, follows E_m = mean over the
//! used bins and directions of |a_{d,k,m}|² (1 for free-field ones from a geometry; the
//! measured gains for HARK zips). With g_m = 10·log10((P_m/E_m) / median_j(P_j/E_j)) (the
//! median taken in dB), a channel with |g_m| ≥ [`GAIN_DB`] has a gain the transfer
//! functions do not know. The whitened GEVD (the robust default) loses
//! talkers at 1–3 dB of such mismatch (docs/accuracy.md, "Gain mismatch and coherence
//! normalisation": 1 dB took a ring's reverberant two-talker windows from 55 to 18 %; a
//! user sweep's room with a far noise source: ±1.5 dB gave 10° errors, ±3 dB lost a
//! talker), while coherence normalisation cancels gains. A noise source within a few
//! array diameters (a drone's rotors) also makes levels unequal with matched gains, so
//! the note names both causes; it is given only where gains matter and are not
//! cancelled (the caller decides: textbook GEVD without coherence).

/// A channel this far (dB) from the median channel's level relative to the transfer
/// functions is reported. Above what near rotors give matched arrays in the project's
/// drone scenes (four rotors 25 cm from the centre: up to 1.1 dB on the 60-mic sphere,
/// under 1 dB on the 8-mic ring), so those pass without a word; mismatches of 1–1.5 dB,
/// which already cost talkers, pass too.
pub const GAIN_DB: f64 = 1.5;

/// The note for microphones with powers `power` (RMS² per microphone) against expected
/// relative powers `expected` (same order), `inputs` their input channels, `skip` the
/// microphones already reported dead or constant; None when all are within [`GAIN_DB`].
pub fn gain_note(power: &[f64], expected: &[f64], inputs: &[usize], skip: &[bool]) -> Option<String> {
    let rel: Vec<Option<f64>> = power
        .iter()
        .zip(expected)
        .zip(skip)
        .map(|((&p, &e), &s)| (!s && p > 0.0 && e > 0.0 && p.is_finite() && e.is_finite()).then(|| p / e))
        .collect();
    let mut sorted: Vec<f64> = rel.iter().flatten().copied().collect();
    if sorted.len() < 2 {
        return None;
    }
    sorted.sort_by(f64::total_cmp);
    // The median in dB (the mean of the middle two for an even count: half the channels
    // 3 dB above the others are ±1.5 dB off, not 0 and −3).
    let n = sorted.len();
    let median = (sorted[(n - 1) / 2] * sorted[n / 2]).sqrt();
    let off: Vec<(usize, f64)> = rel
        .iter()
        .enumerate()
        .filter_map(|(c, r)| r.map(|r| (c, 10.0 * (r / median).log10())))
        .filter(|&(_, g)| g.abs() >= GAIN_DB)
        .collect();
    if off.is_empty() {
        return None;
    }
    let list: Vec<String> = off
        .iter()
        .map(|&(c, g)| format!("{} {g:+.1} dB", inputs[c]))
        .collect();
    Some(format!(
        "warning: input channel levels differ from what the transfer functions expect \
         (relative to the median channel; input channel, 0-based, and its excess): {}. \
         Microphones whose gains differ from the transfer functions' by 1 dB or more cost \
         the GEVD talkers (errors of 10° and more): if the array is not calibrated, \
         normalise the gains with --coherence (coherence=True in Python). A sound source \
         within a few array diameters (a drone's rotors, a talker at arm's length) also \
         makes the levels unequal with matched gains: then ignore this",
        list.join(", ")
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gains_beyond_a_decibel_are_named_relative_to_the_transfer_functions() {
        let inputs: Vec<usize> = (10..15).collect();
        let none = [false; 5];
        // Matched: the powers follow the expected pattern (a measured TF's gains).
        let expected = [1.0, 2.0, 0.5, 1.0, 1.0];
        assert_eq!(gain_note(&expected, &expected, &inputs, &none), None);
        assert_eq!(gain_note(&[3.0; 5], &[1.0; 5], &inputs, &none), None);
        // Channel 12 is 3 dB hot against free-field TFs; 1.4 dB on 11 is within.
        let p = [1.0, 10f64.powf(0.14), 10f64.powf(0.3), 1.0, 1.0];
        let note = gain_note(&p, &[1.0; 5], &inputs, &none).unwrap();
        assert!(note.contains("excess): 12 +3.0 dB."), "{note}");
        assert!(!note.contains(" 11 "), "{note}");
        assert!(note.contains("--coherence"), "{note}");
        // The same powers are what a TF with those gains expects: nothing to say.
        assert_eq!(gain_note(&p, &p, &inputs, &none), None);
        // A dead channel already reported is not a gain; too few channels left: nothing.
        let p = [1.0, 1.0, 1e-4, 1.0, 1.0];
        assert_eq!(
            gain_note(&p, &[1.0; 5], &inputs, &[false, false, true, false, false]),
            None
        );
        assert_eq!(
            gain_note(&[1.0, 4.0], &[1.0; 2], &inputs[..2], &[false, true]),
            None
        );
        // Several off, both signs.
        let p = [1.0, 10f64.powf(-0.2), 10f64.powf(0.2), 1.0, 1.0];
        let note = gain_note(&p, &[1.0; 5], &inputs, &none).unwrap();
        // Half the channels 4 dB above the others: ±2 dB from the median in dB.
        let p = [1.0, 10f64.powf(0.4), 1.0, 10f64.powf(0.4)];
        let half = gain_note(&p, &[1.0; 4], &inputs[..4], &none[..4]).unwrap();
        assert!(
            half.contains("): 10 -2.0 dB, 11 +2.0 dB, 12 -2.0 dB, 13 +2.0 dB."),
            "{half}"
        );
        assert!(note.contains("): 11 -2.0 dB, 12 +2.0 dB."), "{note}");
    }
}
