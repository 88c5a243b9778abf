//! The demo of a sorting station (`sorting:`): push, START once, the live plant feeds the
//! robot's balls past the sensors and gates ([`crate::live_feed`]); each ball's bin is
//! printed as it lands and the whole run is compared with `sim`'s bins
//! (`robot_analysis::sorter::simulate`, the same blobs in virtual time).

use std::io::Write;

use robot_analysis::sorter;
use robot_compiler::Compiled;

use super::bed::{self, Bed};
use super::report::say;
use super::run::{bring_up, finish_with, push_robot, Verdict};
use crate::error::NetError;
use crate::live_feed::{self, Landing};
use crate::live_plant;

/// What a station's demo saw: each ball's bin as it landed (`None`: never), and `sim`'s.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Sorted {
    pub colours: Vec<String>,
    pub bins: Vec<Option<usize>>,
    pub sim: Vec<Option<usize>>,
    /// Balls that met a gate moving: (ball, gate).
    pub met_moving: Vec<(usize, String)>,
}

impl Sorted {
    pub fn ok(&self) -> bool {
        self.bins == self.sim && self.met_moving.is_empty()
    }
}

/// The demo of station `c`: its feed sorted on the bed; says each ball and the verdict.
pub fn run(c: &Compiled, options: bed::Options, out: &mut dyn Write) -> Result<Verdict, NetError> {
    let s =
        (c.robot.sorting.as_ref()).ok_or_else(|| NetError::Robot("no sorting station".into()))?;
    let feed = s.feed.clone();
    let sim = sorter::simulate(c, Some(&feed)).map_err(|e| NetError::Robot(e.to_string()))?;
    let actuators = live_plant::actuators(c)?;
    let addrs = bed::node_addrs(c);
    let mut bed = bring_up(options, &addrs, actuators.clone(), out)?;
    if !push_robot(&mut bed, std::path::Path::new(&c.robot.name), c, out)? {
        finish_with(bed, Verdict::PushFailed, out)?;
        return Ok(Verdict::PushFailed);
    }
    let sorted = sort(
        &mut bed,
        c,
        &feed,
        sim.balls.iter().map(|b| b.bin).collect(),
        out,
    )?;
    let verdict = if sorted.ok() {
        Verdict::Matched
    } else {
        Verdict::Mismatch
    };
    finish_with(bed, verdict, out)?;
    Ok(verdict)
}

/// Presses START on a pushed station and follows its feed until every ball landed (each
/// within the bed's timeout) or one did not.
pub fn sort(
    bed: &mut Bed,
    c: &Compiled,
    feed: &[String],
    sim: Vec<Option<usize>>,
    out: &mut dyn Write,
) -> Result<Sorted, NetError> {
    let actuators = live_plant::actuators(c)?;
    let balls = live_feed::ball_feed(c, &actuators, feed)?;
    let landed = bed.set_plant_fed(actuators, balls)?;
    say(
        out,
        &format!("feed: {} ball(s): {}", feed.len(), feed.join(" ")),
    );
    bed.press_start(c)?;
    let mut sorted = Sorted {
        colours: feed.to_vec(),
        bins: vec![None; feed.len()],
        sim,
        met_moving: Vec::new(),
    };
    let mut left = feed.len();
    while left > 0 {
        let Ok(Landing {
            ball,
            bin,
            met_moving,
            at,
        }) = landed.recv_timeout(bed.timeout())
        else {
            say(
                out,
                &format!(
                    "STALLED: {left} ball(s) not landed within {} s",
                    bed.timeout().as_secs()
                ),
            );
            break;
        };
        let Some(slot) = sorted.bins.get_mut(ball) else {
            continue;
        };
        *slot = Some(bin);
        left -= 1;
        let want = sorted.sim.get(ball).copied().flatten();
        let same = if want == Some(bin) {
            String::from("as sim")
        } else {
            format!("sim: bin {}", want.map_or("none".into(), |b| b.to_string()))
        };
        say(
            out,
            &format!(
                "  {:>7.3} s  ball {:>3}: {:<8} bin {bin}  ({same})",
                at.as_secs_f64(),
                ball + 1,
                feed.get(ball).map_or("?", String::as_str)
            ),
        );
        for g in met_moving {
            say(out, &format!("  ball {} met gate {g} moving", ball + 1));
            sorted.met_moving.push((ball, g));
        }
    }
    let count = |bins: &[Option<usize>]| {
        let top = bins.iter().flatten().max().copied().unwrap_or(1);
        (1..=top)
            .map(|n| {
                format!(
                    "bin {n}: {}",
                    bins.iter().filter(|b| **b == Some(n)).count()
                )
            })
            .collect::<Vec<_>>()
            .join(", ")
    };
    say(
        out,
        &format!(
            "sorted: {}; sim: {}; {}",
            count(&sorted.bins),
            count(&sorted.sim),
            if sorted.ok() {
                "every ball in sim's bin"
            } else {
                "DIFFERENT from sim"
            }
        ),
    );
    Ok(sorted)
}
