//! The panel's eyes on the air: a monitor on the medium whose pin changes (valves the
//! nodes drive, switches the plant sets, stamped with the medium's clock) go to the live
//! machine as they come, so a pin change is on the page within the time of one read.

use std::io;
use std::net::SocketAddr;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use config_schema::wire::mac::Frame;
use config_schema::wire::medium::{Link, Peer};
use config_schema::wire::msg::Message;
use medium::Conn;
use robot_keys::MachineSecret;
use robot_net::sniff::Sniffer;

use crate::model::Machine;
use crate::shared::Shared;

/// How often time is looked at between pin changes (actuators without switches arrive
/// by their plant time; a motion past its plant time is late).
const TICK: Duration = Duration::from_millis(20);

/// What the monitor takes from the medium.
enum Heard {
    Pin(u64, u16, u8, bool, bool),
    /// (publisher, epoch, seq, topic)
    Event(u16, u16, u16, u8),
}

/// The event a frame carries, if it is one (a secured one opened with `keys`).
fn event(psdu: &[u8], keys: &mut Sniffer) -> Option<Heard> {
    let Ok(Frame::Data { header, payload }) = Frame::parse(psdu) else {
        return None;
    };
    let plain;
    let payload = if header.secured {
        plain = keys.open(psdu).ok()?;
        &plain[..]
    } else {
        payload
    };
    match Message::parse(payload).ok()? {
        Message::Event { epoch, seq, topic } => Some(Heard::Event(header.src, epoch, seq, topic)),
        _ => None,
    }
}

/// Joins the medium at `medium` as a monitor (it sees every pin change once this
/// returns) and feeds `shared` until `stop`, or until the medium goes away (then the
/// live machine says so). The machine's events are read with `secret` (secured), for
/// table generation `generation`.
pub fn start(
    medium: SocketAddr,
    machine: Arc<Machine>,
    shared: Arc<Shared>,
    keys: (Option<MachineSecret>, u32),
    stop: Arc<AtomicBool>,
) -> io::Result<JoinHandle<()>> {
    let mut conn = Conn::join(medium, Peer::Monitor)?;
    let mut sniffer = Sniffer::new(keys.0, Some(keys.1));
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
                    } => Some(Heard::Pin(at_us, addr, pin, level, output)),
                    Link::Frame(psdu) => event(psdu, &mut sniffer),
                    _ => None,
                });
                let now = clock.0 + clock.1.elapsed().as_micros() as u64;
                match got {
                    Ok(Some(Heard::Pin(at_us, addr, pin, level, output))) => {
                        clock = (at_us, Instant::now());
                        shared.update(|l| {
                            l.pin(&machine, at_us, addr, pin, level, output);
                            true
                        });
                    }
                    Ok(Some(Heard::Event(src, epoch, seq, topic))) => shared.update(|l| {
                        let before = l.event_count;
                        l.event(&machine, now, src, epoch, seq, topic);
                        l.event_count != before
                    }),
                    Ok(None) => {
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
