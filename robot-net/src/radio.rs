//! The tool's radio: a connection to the medium as `Peer::Tool`, speaking IEEE 802.15.4
//! frames and application messages like any node.

use std::io;
use std::net::SocketAddr;
use std::time::{Duration, Instant};

use config_schema::wire::mac::{self, Frame, Header, MAX_PSDU};
use config_schema::wire::medium::{Link, Peer};
use config_schema::wire::msg::Message;
use node_fw::node::CONFIG_PAN;

use medium::Conn;

/// The tool's default short address.
pub const TOOL_ADDR: u16 = 0x0100;

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
        })
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
        let len = mac::emit_data(&header, &payload[..n], &mut psdu)
            .map_err(|_| io::Error::other("frame too long"))?;
        self.stats.sent += 1;
        let airtime = mac::airtime_us(len) + mac::airtime_us(ANSWER_PSDU);
        self.air_clear = self.air_clear.max(Instant::now()) + Duration::from_micros(airtime.into());
        self.conn.send(&Link::Frame(&psdu[..len]))
    }

    /// The next message for this radio, or `None` when `until` passes.
    pub fn recv(&mut self, until: Instant) -> io::Result<Option<Received>> {
        let (me, stats) = (self.addr, &mut self.stats);
        self.conn.recv(until, |link| {
            let Link::Frame(psdu) = link else { return None };
            match Frame::parse(psdu) {
                Ok(Frame::Data { header, payload })
                    if header.dst == me || header.dst == mac::BROADCAST =>
                {
                    stats.received += 1;
                    Some(Received {
                        src: header.src,
                        payload: payload.to_vec(),
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
