//! The test bed's eyes on the air: a monitor on the medium that reports, stamped with the
//! medium's clock, every fault a node publishes and every output level a node drives, as
//! they happen (the demo reports a fault when it happens, not when a cycle times out).

use std::collections::HashMap;
use std::io;
use std::net::SocketAddr;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::Sender;
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use config_schema::wire::mac::Frame;
use config_schema::wire::medium::{Link, Peer};
use config_schema::wire::msg::Message;

use medium::Conn;
use robot_compiler::compile::Compiled;

use crate::sniff::Sniffer;

/// Something the monitor saw, at `at` on the medium's clock.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Seen {
    /// Node `addr` (playing `role`) published its fault.
    Fault {
        at: Duration,
        addr: u16,
        role: String,
    },
    /// Node `addr` drove output `pin` to `level`.
    Output {
        at: Duration,
        addr: u16,
        pin: u8,
        level: bool,
    },
}

/// Which (publisher address, topic) is a role's fault publication.
pub fn fault_topics(c: &Compiled) -> HashMap<(u16, u8), String> {
    robot_compiler::lower::topics(&c.ir)
        .into_iter()
        .filter_map(|(ri, e, topic)| {
            let role = c.ir.roles.get(ri)?;
            let name = role.events.get(e)?;
            let topic = u8::try_from(topic).ok()?;
            (name == robot_compiler::synth::FAULT_EVENT)
                .then(|| ((role.address, topic), role.name.clone()))
        })
        .collect()
}

/// A running monitor; stops when dropped.
pub struct Watch {
    stop: Arc<AtomicBool>,
    handle: Option<JoinHandle<io::Result<()>>>,
}

impl Watch {
    /// Joins `medium` as a monitor (it sees everything once this returns) and sends what
    /// it sees to `out`. `clock` is when the medium started (frames carry no stamp: a
    /// frame's time is when the monitor got it, as it left the air).
    pub fn start(
        medium: SocketAddr,
        clock: Instant,
        faults: HashMap<(u16, u8), String>,
        mut keys: Option<Sniffer>,
        out: Sender<Seen>,
    ) -> io::Result<Watch> {
        let mut conn = Conn::join(medium, Peer::Monitor)?;
        let stop = Arc::new(AtomicBool::new(false));
        let flag = stop.clone();
        let handle = std::thread::Builder::new()
            .name("demo-watch".into())
            .spawn(move || {
                while !flag.load(Ordering::Relaxed) {
                    let until = Instant::now() + Duration::from_millis(100);
                    let seen =
                        conn.recv(until, |link| seen(&link, clock, &faults, keys.as_mut()))?;
                    if let Some(s) = seen {
                        if out.send(s).is_err() {
                            break;
                        }
                    }
                }
                Ok(())
            })?;
        Ok(Watch {
            stop,
            handle: Some(handle),
        })
    }
}

impl Drop for Watch {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(h) = self.handle.take() {
            let _ = h.join();
        }
    }
}

/// What one medium message says, if it is worth reporting.
/// A secured frame is read with `keys` (the machine's events are secured).
fn seen(
    link: &Link,
    clock: Instant,
    faults: &HashMap<(u16, u8), String>,
    keys: Option<&mut Sniffer>,
) -> Option<Seen> {
    if let Some((at_us, addr, pin, level)) = link.output_seen() {
        return Some(Seen::Output {
            at: Duration::from_micros(at_us),
            addr,
            pin,
            level,
        });
    }
    match *link {
        Link::Frame(psdu) => {
            let Ok(Frame::Data { header, payload }) = Frame::parse(psdu) else {
                return None;
            };
            let plain;
            let payload = match (header.secured, keys) {
                (false, _) => payload,
                (true, Some(k)) => {
                    plain = k.open(psdu).ok()?;
                    &plain[..]
                }
                (true, None) => return None,
            };
            let Ok(Message::Event { topic, .. }) = Message::parse(payload) else {
                return None;
            };
            let role = faults.get(&(header.src, topic))?;
            Some(Seen::Fault {
                at: clock.elapsed(),
                addr: header.src,
                role: role.clone(),
            })
        }
        _ => None,
    }
}
