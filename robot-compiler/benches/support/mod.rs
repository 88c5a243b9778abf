//! What the benches share.

use std::time::Instant;

/// Mean seconds per run of `f`, over at least `min` runs and 0.2 s.
pub fn time(min: u32, mut f: impl FnMut()) -> f64 {
    let start = Instant::now();
    let mut n = 0;
    while n < min || start.elapsed().as_secs_f64() < 0.2 {
        f();
        n += 1;
    }
    start.elapsed().as_secs_f64() / f64::from(n)
}
