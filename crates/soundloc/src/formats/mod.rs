//! File formats robot-audition users already have (HARK's), read and written.
