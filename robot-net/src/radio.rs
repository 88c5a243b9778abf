//! The tool's radio: a connection to the medium as `Peer::Tool`, speaking IEEE 802.15.4
//! frames and application messages like any node.

use std::io;
use std::net::SocketAddr;
use std::time::{Duration, Instant};

use config_schema::wire::mac::{self, Frame, Header, MAX_PSDU};
use config_schema::wire::medium::{Link, Peer};
use config_schema::wire::msg::Message;
use config_schema::wire::security::{
    self, ext_addr, replay::ReplayGuard, AuxRepr, SecurityLevel, DEFAULT_OVERHEAD,
};
use node_fw::node::{CONFIG_PAN, MANAGEMENT_KEY_INDEX};
use robot_keys::{management_key, MachineSecret};

use medium::Conn;

pub use config_schema::wire::TOOL_ADDR;

/// The PSDU length of a node's answer to a frame of the tool (a `ConfigReply::Next` is
/// 18 bytes; a status is longer, and rarer).
const ANSWER_PSDU: usize = 24;

/// A received application message, owned.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Received {
    pub src: u16,
    pub payload: Vec<u8>,
}

impl Received {
    /// The message (borrowing the payload).
    pub fn message(&self) -> Option<Message<'_>> {
        Message::parse(&self.payload).ok()
    }
}

/// Counters of the tool's radio.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct RadioStats {
    pub sent: u64,
    pub received: u64,
    /// Frames that failed their FCS or did not parse.
    pub dropped: u64,
    /// With keys: frames from nodes refused (unsecured, bad MIC, replayed, ...).
    pub refused: u64,
    /// With keys: challenges from nodes answered (each node's first exchange after boot).
    pub challenges: u64,
}

/// How recent an unanswered message must be to be sent again after a challenge.
pub const RESEND_WITHIN: Duration = Duration::from_millis(500);

/// Nodes whose last frame counter the tool remembers (one entry per node it heard).
pub const TOOL_SENDERS: usize = 256;

/// The source of the tool's frame counters: never one handed out before under the same
/// machine secret, by any run of the tool (an error: used up, or its file failed or stayed
/// locked; nothing is sent, and the error says why).
pub type CounterSource = Box<dyn FnMut() -> io::Result<u32>>;

/// What a secured tool radio holds: the machine secret (each node's management key is
/// derived from it), its frame counter, and the last counter accepted from each node.
struct Keys {
    secret: MachineSecret,
    counter: CounterSource,
    replay: ReplayGuard<TOOL_SENDERS>,
    /// The last message sent to each node and when, while unanswered: sent again after
    /// answering the node's challenge.
    last_sent: std::collections::HashMap<u16, (Instant, Vec<u8>)>,
    /// Nodes whose challenge was answered since [`ToolRadio::take_challengers`].
    challengers: std::collections::BTreeSet<u16>,
    /// Nodes whose challenge was answered and that have sent nothing else since: the
    /// answer was lost, so the next one goes out twice.
    unheard: std::collections::BTreeSet<u16>,
}

/// The tool on the medium.
pub struct ToolRadio {
    conn: Conn,
    addr: u16,
    seq: u8,
    /// When the frames this radio sent, and the short answer each one asks for, are off the
    /// air at the earliest (250 kbit/s, one after the other): what a reply to the last of
    /// them waits for.
    air_clear: Instant,
    pub stats: RadioStats,
    keys: Option<Keys>,
    /// Unsecured because the robot says `security: Off` (not for want of keys).
    plain_chosen: bool,
}

impl ToolRadio {
    /// Connects to the medium at `medium` as the radio with short address `addr`; returns
    /// once the medium routes to it.
    pub fn connect(medium: SocketAddr, addr: u16) -> io::Result<ToolRadio> {
        Ok(ToolRadio {
            conn: Conn::join(medium, Peer::Tool { addr })?,
            addr,
            seq: 0,
            air_clear: Instant::now(),
            stats: RadioStats::default(),
            keys: None,
            plain_chosen: false,
        })
    }

    /// From now on, what this radio sends to a node is secured with that node's
    /// management key (ENC-MIC-64, key index 0), numbered by `counter`, and what it
    /// receives is taken only secured by the sender's key with a fresh counter. Broadcasts
    /// (a scan's Identify) stay unsecured: no one key covers every node.
    pub fn secure(&mut self, secret: MachineSecret, counter: CounterSource) {
        self.keys = Some(Keys {
            secret,
            counter,
            replay: ReplayGuard::new(),
            last_sent: Default::default(),
            challengers: Default::default(),
            unheard: Default::default(),
        });
    }

    /// The link keys of `node` for a table of `generation` with `peers`, derived from the
    /// machine secret; `None` when the radio is not secured.
    pub fn link_keys(
        &self,
        generation: u32,
        node: u16,
        peers: &[u16],
    ) -> Option<config_schema::link_keys::LinkKeys> {
        let keys = self.keys.as_ref()?;
        robot_keys::link_keys(&keys.secret, generation, node, peers)
    }

    /// Whether the radio secures its frames.
    pub fn secured(&self) -> bool {
        self.keys.is_some()
    }

    /// Marks this radio unsecured by the robot's choice (`security: Off`): its nodes take
    /// frames in clear, so a silent one is not one that wants keys.
    pub fn choose_plain(&mut self) {
        self.plain_chosen = true;
    }

    /// Whether the robot chose frames in clear ([`ToolRadio::choose_plain`]).
    pub fn plain_chosen(&self) -> bool {
        self.plain_chosen
    }

    pub fn addr(&self) -> u16 {
        self.addr
    }

    /// When the frames sent so far are off the air at the earliest.
    pub fn air_clear(&self) -> Instant {
        self.air_clear
    }

    /// Sends `msg` to `dst` (a node or the broadcast address) on the configuration PAN.
    pub fn send(&mut self, dst: u16, msg: &Message) -> io::Result<()> {
        let mut payload = [0u8; mac::MAX_PAYLOAD];
        let n = msg
            .emit(&mut payload)
            .map_err(|_| io::Error::other("message does not fit a frame"))?;
        if let Some(keys) = self.keys.as_mut().filter(|_| dst != mac::BROADCAST) {
            keys.last_sent
                .insert(dst, (Instant::now(), payload[..n].to_vec()));
        }
        self.send_payload(dst, &payload[..n])
    }

    /// Sends a message's bytes to `dst` (secured to a node when the radio has keys).
    fn send_payload(&mut self, dst: u16, payload: &[u8]) -> io::Result<()> {
        let header = Header {
            seq: self.seq,
            pan_id: CONFIG_PAN,
            dst,
            src: self.addr,
            ack_request: false,
            secured: false,
        };
        self.seq = self.seq.wrapping_add(1);
        let mut psdu = [0u8; MAX_PSDU];
        let len = match self.keys.as_mut().filter(|_| dst != mac::BROADCAST) {
            Some(keys) => {
                let counter = (keys.counter)()?;
                let key = management_key(&keys.secret, dst);
                security::secure(
                    &header,
                    &AuxRepr::new(MANAGEMENT_KEY_INDEX, counter),
                    key.expose(),
                    ext_addr(CONFIG_PAN, self.addr),
                    payload,
                    &mut psdu,
                )
                .map_err(|e| io::Error::other(format!("cannot secure the frame: {e}")))?
            }
            None => mac::emit_data(&header, payload, &mut psdu)
                .map_err(|_| io::Error::other("frame too long"))?,
        };
        self.stats.sent += 1;
        // A secured answer carries the auxiliary header and the MIC too.
        let answer = ANSWER_PSDU
            + if self.keys.is_some() {
                DEFAULT_OVERHEAD
            } else {
                0
            };
        let airtime = mac::airtime_us(len) + mac::airtime_us(answer);
        self.air_clear = self.air_clear.max(Instant::now()) + Duration::from_micros(airtime.into());
        self.conn.send(&Link::Frame(&psdu[..len]))
    }

    /// The next message for this radio, or `None` when `until` passes.
    ///
    /// With keys, a node's `Challenge` (it rebooted and does not know the tool's counter
    /// yet) is answered here, and the last message sent to that node is sent again at
    /// once, so the protocols above see no loss.
    pub fn recv(&mut self, until: Instant) -> io::Result<Option<Received>> {
        loop {
            let Some(r) = self.recv_one(until)? else {
                return Ok(None);
            };
            match (self.keys.is_some(), r.message()) {
                (true, Some(Message::Challenge { nonce })) => {
                    self.stats.challenges += 1;
                    let mut answer = [0u8; 16];
                    let n = Message::ChallengeAnswer { nonce }
                        .emit(&mut answer)
                        .map_err(|_| io::Error::other("challenge answer"))?;
                    // A lost answer costs a whole round (the node challenges again only
                    // when a retry reaches it, at most once per `CHALLENGE_MS`): once one
                    // was lost, the answers to that node go out twice (the second copy is
                    // an authentic frame the node ignores).
                    let again = self.keys.as_mut().is_some_and(|k| {
                        k.challengers.insert(r.src);
                        !k.unheard.insert(r.src)
                    });
                    self.send_payload(r.src, &answer[..n])?;
                    if again {
                        self.send_payload(r.src, &answer[..n])?;
                    }
                    // Sent again once, and only if it is still unanswered and recent: a
                    // challenge an attacker provokes later (by replaying a frame) must not
                    // make the tool repeat a command the node already took.
                    let last = self.keys.as_mut().and_then(|k| k.last_sent.remove(&r.src));
                    if let Some((_, last)) = last.filter(|(at, _)| at.elapsed() < RESEND_WITHIN) {
                        self.send_payload(r.src, &last)?;
                    }
                }
                _ => {
                    // An answer: what was sent to that node was taken.
                    if let Some(k) = self.keys.as_mut() {
                        k.last_sent.remove(&r.src);
                        k.unheard.remove(&r.src);
                    }
                    return Ok(Some(r));
                }
            }
        }
    }

    /// The nodes that challenged this radio (and were answered) since the last call: they
    /// are there, even if what was sent to them is not answered yet.
    pub fn take_challengers(&mut self) -> Vec<u16> {
        (self.keys.as_mut())
            .map(|k| std::mem::take(&mut k.challengers).into_iter().collect())
            .unwrap_or_default()
    }

    fn recv_one(&mut self, until: Instant) -> io::Result<Option<Received>> {
        let (me, stats, keys) = (self.addr, &mut self.stats, &mut self.keys);
        self.conn.recv(until, |link| {
            let Link::Frame(psdu) = link else { return None };
            match Frame::parse(psdu) {
                Ok(Frame::Data { header, payload })
                    if header.dst == me || header.dst == mac::BROADCAST =>
                {
                    let payload = match keys {
                        Some(keys) => match open(keys, psdu) {
                            Some(p) => p,
                            None => {
                                stats.refused += 1;
                                return None;
                            }
                        },
                        None if header.secured => {
                            stats.dropped += 1;
                            return None;
                        }
                        None => payload.to_vec(),
                    };
                    stats.received += 1;
                    Some(Received {
                        src: header.src,
                        payload,
                    })
                }
                Ok(_) => None,
                Err(_) => {
                    stats.dropped += 1;
                    None
                }
            }
        })
    }
}

/// A node's frame to the tool, opened with that node's management key and replay-checked;
/// `None` if it is not secured so, or not fresh.
fn open(keys: &mut Keys, psdu: &[u8]) -> Option<Vec<u8>> {
    let mut scratch = [0u8; mac::MAX_PAYLOAD];
    let secret = &keys.secret;
    let opened = security::open_at(
        psdu,
        SecurityLevel::EncMic64,
        |header, aux| {
            (aux.key_id.index() == Some(MANAGEMENT_KEY_INDEX)).then(|| {
                let key = management_key(secret, header.src);
                (*key.expose(), ext_addr(header.pan_id, header.src))
            })
        },
        &mut scratch,
    )
    .ok()?;
    keys.replay
        .check_and_accept(
            opened.header.src,
            MANAGEMENT_KEY_INDEX,
            opened.aux.frame_counter,
        )
        .ok()?;
    Some(opened.payload.to_vec())
}

#[cfg(test)]
mod tests {
    use super::*;
    use config_schema::wire::msg::Command;

    const NODE: u16 = 0x0011;

    fn secret(b: u8) -> MachineSecret {
        MachineSecret::from_bytes([b; 32])
    }

    fn counter_from(mut next: u32) -> CounterSource {
        Box::new(move || {
            let n = next;
            next += 1;
            Ok(n)
        })
    }

    fn status_payload(ack: u16) -> Vec<u8> {
        let msg = Message::Command {
            id: ack,
            command: Command::Identify { nonce: 1 },
        };
        let mut buf = [0u8; mac::MAX_PAYLOAD];
        let n = msg.emit(&mut buf).unwrap();
        buf[..n].to_vec()
    }

    /// A frame from the node to the tool: secured under `key_of`'s key for the node, or not.
    fn from_node(key_of: Option<&MachineSecret>, counter: u32, payload: &[u8]) -> Vec<u8> {
        let header = Header {
            seq: 0,
            pan_id: CONFIG_PAN,
            dst: TOOL_ADDR,
            src: NODE,
            ack_request: false,
            secured: false,
        };
        let mut psdu = [0u8; MAX_PSDU];
        let n = match key_of {
            Some(s) => security::secure(
                &header,
                &AuxRepr::new(MANAGEMENT_KEY_INDEX, counter),
                management_key(s, NODE).expose(),
                ext_addr(CONFIG_PAN, NODE),
                payload,
                &mut psdu,
            )
            .unwrap(),
            None => mac::emit_data(&header, payload, &mut psdu).unwrap(),
        };
        psdu[..n].to_vec()
    }

    #[test]
    fn a_secured_radio_takes_only_the_nodes_fresh_secured_frames() {
        let medium = medium::Medium::start(medium::Config::default()).unwrap();
        let mut tool = ToolRadio::connect(medium.addr(), TOOL_ADDR).unwrap();
        tool.secure(secret(1), counter_from(0));
        let mut node = Conn::join(medium.addr(), Peer::Node { addr: NODE }).unwrap();
        let good = from_node(Some(&secret(1)), 5, &status_payload(1));
        // Unsecured, another machine's key, the good one, its replay, then a fresh one.
        for psdu in [
            from_node(None, 0, &status_payload(9)),
            from_node(Some(&secret(2)), 6, &status_payload(9)),
            good.clone(),
            good,
            from_node(Some(&secret(1)), 6, &status_payload(2)),
        ] {
            node.send(&Link::Frame(&psdu)).unwrap();
        }
        let end = Instant::now() + Duration::from_secs(30);
        let mut got = Vec::new();
        while got.len() < 2 {
            let r = tool.recv(end).unwrap().expect("two frames get through");
            got.push(r.payload);
        }
        assert_eq!(got, [status_payload(1), status_payload(2)]);
        assert_eq!((tool.stats.received, tool.stats.refused), (2, 3));
        medium.stop();
    }

    /// What the node received, opened with its key.
    fn node_gets(node: &mut Conn, n: usize) -> Vec<Vec<u8>> {
        let end = Instant::now() + Duration::from_secs(30);
        let key = management_key(&secret(1), NODE);
        let mut got = Vec::new();
        while got.len() < n {
            let f = node
                .recv(end, |l| match l {
                    Link::Frame(p) => Some(p.to_vec()),
                    _ => None,
                })
                .unwrap()
                .expect("a frame");
            let mut scratch = [0u8; mac::MAX_PAYLOAD];
            let o = security::open_at(
                &f,
                SecurityLevel::EncMic64,
                |h, _| Some((*key.expose(), ext_addr(h.pan_id, h.src))),
                &mut scratch,
            )
            .expect("secured");
            got.push(o.payload.to_vec());
        }
        got
    }

    fn emit(msg: &Message<'_>) -> Vec<u8> {
        let mut buf = [0u8; mac::MAX_PAYLOAD];
        let n = msg.emit(&mut buf).unwrap();
        buf[..n].to_vec()
    }

    /// Receives until `tool` has answered `n` challenges in all (by `end` at the latest):
    /// they are handled inside recv, never handed up.
    fn challenged_until(tool: &mut ToolRadio, n: u64, end: Instant) {
        while tool.stats.challenges < n && Instant::now() < end {
            let r = tool
                .recv(Instant::now() + Duration::from_millis(50))
                .unwrap();
            assert_eq!(r, None);
        }
    }

    #[test]
    fn a_challenge_is_answered_twice_once_an_answer_was_lost_and_only_an_unanswered_message_sent_again(
    ) {
        let medium = medium::Medium::start(medium::Config::default()).unwrap();
        let mut tool = ToolRadio::connect(medium.addr(), TOOL_ADDR).unwrap();
        tool.secure(secret(1), counter_from(0));
        let mut node = Conn::join(medium.addr(), Peer::Node { addr: NODE }).unwrap();
        let start = Message::Command {
            id: 1,
            command: Command::Start,
        };
        tool.send(NODE, &start).unwrap();
        assert_eq!(node_gets(&mut node, 1), [emit(&start)]);
        // The node (just booted) challenges: the tool answers, then sends the START again.
        let challenge = |nonce, counter| {
            from_node(
                Some(&secret(1)),
                counter,
                &emit(&Message::Challenge { nonce }),
            )
        };
        node.send(&Link::Frame(&challenge(70, 70))).unwrap();
        let end = Instant::now() + Duration::from_secs(30);
        challenged_until(&mut tool, 1, end);
        let answer = Message::ChallengeAnswer { nonce: 70 };
        assert_eq!(node_gets(&mut node, 2), [emit(&answer), emit(&start)]);
        assert_eq!(tool.take_challengers(), [NODE]);
        assert_eq!(tool.take_challengers(), []);
        // The node answers; a later challenge (a replay provoked it) repeats nothing.
        node.send(&Link::Frame(&from_node(
            Some(&secret(1)),
            71,
            &status_payload(1),
        )))
        .unwrap();
        node.send(&Link::Frame(&challenge(72, 72))).unwrap();
        assert!(tool.recv(end).unwrap().is_some(), "the answer");
        challenged_until(&mut tool, 2, end);
        // Nothing else came before a marker the tool sends next.
        let marker = Message::Command {
            id: 2,
            command: Command::Status,
        };
        tool.send(NODE, &marker).unwrap();
        let answer = Message::ChallengeAnswer { nonce: 72 };
        assert_eq!(node_gets(&mut node, 2), [emit(&answer), emit(&marker)]);
        assert_eq!(tool.stats.challenges, 2);
        // Challenged again with nothing else heard: that answer was lost, this one goes
        // out twice.
        node.send(&Link::Frame(&challenge(74, 74))).unwrap();
        challenged_until(&mut tool, 3, end);
        let answer = Message::ChallengeAnswer { nonce: 74 };
        assert_eq!(node_gets(&mut node, 2), [emit(&answer), emit(&answer)]);
        medium.stop();
    }

    #[test]
    fn a_secured_radio_secures_to_a_node_and_broadcasts_in_clear() {
        let medium = medium::Medium::start(medium::Config::default()).unwrap();
        let mut tool = ToolRadio::connect(medium.addr(), TOOL_ADDR).unwrap();
        tool.secure(secret(1), counter_from(40));
        let mut node = Conn::join(medium.addr(), Peer::Node { addr: NODE }).unwrap();
        let msg = Message::Command {
            id: 3,
            command: Command::Start,
        };
        tool.send(NODE, &msg).unwrap();
        tool.send(mac::BROADCAST, &msg).unwrap();
        let end = Instant::now() + Duration::from_secs(30);
        let mut frames = Vec::new();
        while frames.len() < 2 {
            let f = node
                .recv(end, |l| match l {
                    Link::Frame(p) => Some(p.to_vec()),
                    _ => None,
                })
                .unwrap()
                .expect("both frames");
            frames.push(f);
        }
        let key = management_key(&secret(1), NODE);
        let mut scratch = [0u8; mac::MAX_PAYLOAD];
        let opened = security::open_at(
            &frames[0],
            SecurityLevel::EncMic64,
            |h, _| Some((*key.expose(), ext_addr(h.pan_id, h.src))),
            &mut scratch,
        )
        .expect("secured with the node's key");
        assert_eq!(opened.aux.frame_counter, 40);
        assert_eq!(Message::parse(opened.payload), Ok(msg.clone()));
        match Frame::parse(&frames[1]) {
            Ok(Frame::Data { header, payload }) => {
                assert!(!header.secured);
                assert_eq!(Message::parse(payload), Ok(msg));
            }
            other => panic!("not a data frame: {other:?}"),
        }
        medium.stop();
    }
}
