//! The panel's eyes on the air: a monitor on the medium whose pin changes (valves the
//! nodes drive, switches the plant sets, stamped with the medium's clock) go to the live
//! machine as they come, so a pin change is on the page within the time of one read.

use std::io;
use std::net::SocketAddr;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use config_schema::wire::medium::{Link, Peer};
use medium::Conn;

use crate::model::Machine;
use crate::shared::Shared;

/// How often time is looked at between pin changes (actuators without switches arrive
/// by their plant time; a motion past its plant time is late).
const TICK: Duration = Duration::from_millis(20);

/// Joins the medium at `medium` as a monitor (it sees every pin change once this
/// returns) and feeds `shared` until `stop`, or until the medium goes away (then the
/// live machine says so).
pub fn start(
    medium: SocketAddr,
    machine: Arc<Machine>,
    shared: Arc<Shared>,
    stop: Arc<AtomicBool>,
) -> io::Result<JoinHandle<()>> {
    let mut conn = Conn::join(medium, Peer::Monitor)?;
    std::thread::Builder::new()
        .name("panel-feed".into())
        .spawn(move || {
            // The medium's clock: the last stamp heard, and when.
            let mut clock = (0u64, Instant::now());
            while !stop.load(Ordering::Relaxed) {
                let got = conn.recv(Instant::now() + TICK, |link| match link {
                    Link::Seen {
                        at_us,
                        addr,
                        pin,
                        level,
                        output,
                    } => Some((at_us, addr, pin, level, output)),
                    _ => None,
                });
                match got {
                    Ok(Some((at_us, addr, pin, level, output))) => {
                        clock = (at_us, Instant::now());
                        shared.update(|l| {
                            l.pin(&machine, at_us, addr, pin, level, output);
                            true
                        });
                    }
                    Ok(None) => {
                        let now = clock.0 + clock.1.elapsed().as_micros() as u64;
                        shared.update(|l| {
                            let before = l.lanes.clone();
                            l.tick(&machine, now);
                            l.lanes != before
                        });
                    }
                    Err(e) => {
                        let why = match e.kind() {
                            io::ErrorKind::UnexpectedEof => "the medium closed".to_string(),
                            _ => format!("the medium failed: {e}"),
                        };
                        shared.update(|l| {
                            l.medium_lost.get_or_insert(why);
                            l.running = false;
                            true
                        });
                        return;
                    }
                }
            }
        })
}
