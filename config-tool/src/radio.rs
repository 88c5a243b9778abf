//! The tool's radio: a connection to the medium as `Peer::Tool`, speaking IEEE 802.15.4
//! frames and application messages like any node.

use std::io::{self, Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::time::{Duration, Instant};

use config_schema::wire::mac::{self, Frame, Header, MAX_PSDU};
use config_schema::wire::medium::{next_message, Link, Peer, MAX_LINK};
use config_schema::wire::msg::Message;
use node_fw::node::CONFIG_PAN;

/// The tool's default short address.
pub const TOOL_ADDR: u16 = 0x0100;

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
    stream: TcpStream,
    addr: u16,
    seq: u8,
    buf: Vec<u8>,
    pub stats: RadioStats,
}

impl ToolRadio {
    /// Connects to the medium at `medium` as the radio with short address `addr`.
    pub fn connect(medium: SocketAddr, addr: u16) -> io::Result<ToolRadio> {
        let stream = TcpStream::connect_timeout(&medium, Duration::from_secs(5))?;
        stream.set_nodelay(true)?;
        let mut radio = ToolRadio {
            stream,
            addr,
            seq: 0,
            buf: Vec::new(),
            stats: RadioStats::default(),
        };
        radio.write(&Link::Hello(Peer::Tool { addr }))?;
        Ok(radio)
    }

    pub fn addr(&self) -> u16 {
        self.addr
    }

    fn write(&mut self, link: &Link) -> io::Result<()> {
        let mut buf = [0u8; MAX_LINK];
        let n = link
            .emit(&mut buf)
            .map_err(|_| io::Error::other("message too long"))?;
        self.stream.write_all(&buf[..n])
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
        self.write(&Link::Frame(&psdu[..len]))
    }

    /// The next message for this radio, or `None` when `until` passes.
    pub fn recv(&mut self, until: Instant) -> io::Result<Option<Received>> {
        loop {
            while let Some(body) = next_message(&self.buf) {
                let link = Link::parse(&self.buf[body.clone()]);
                let got = match link {
                    Ok(Link::Frame(psdu)) => match Frame::parse(psdu) {
                        Ok(Frame::Data { header, payload })
                            if header.dst == self.addr || header.dst == mac::BROADCAST =>
                        {
                            self.stats.received += 1;
                            Some(Received {
                                src: header.src,
                                payload: payload.to_vec(),
                            })
                        }
                        Ok(_) => None,
                        Err(_) => {
                            self.stats.dropped += 1;
                            None
                        }
                    },
                    _ => None,
                };
                self.buf.drain(..body.end);
                if got.is_some() {
                    return Ok(got);
                }
            }
            let now = Instant::now();
            if now >= until {
                return Ok(None);
            }
            self.stream
                .set_read_timeout(Some((until - now).max(Duration::from_millis(1))))?;
            let mut chunk = [0u8; 2048];
            match self.stream.read(&mut chunk) {
                Ok(0) => {
                    return Err(io::Error::new(
                        io::ErrorKind::UnexpectedEof,
                        "the medium closed the connection",
                    ))
                }
                Ok(n) => self.buf.extend_from_slice(&chunk[..n]),
                Err(e)
                    if e.kind() == io::ErrorKind::WouldBlock
                        || e.kind() == io::ErrorKind::TimedOut => {}
                Err(e) => return Err(e),
            }
        }
    }
}
