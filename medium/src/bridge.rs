//! A medium bridged to the air: every frame on the medium goes to an nRF52840 gateway on a
//! serial line (the medium's framing), and every frame the gateway hears goes on the
//! medium. The bridge joins the medium as a monitor (it sees every frame, without the
//! medium's loss).

use std::io::{self, Read, Write};
use std::net::SocketAddr;
use std::path::Path;
use std::thread::JoinHandle;

use config_schema::wire::mac::MAX_PSDU;
use config_schema::wire::medium::{Deframer, Link, Peer, MAX_LINK};

use crate::{Config, Conn, Medium};

/// Why a bridge did not start.
#[derive(Debug, thiserror::Error)]
pub enum BridgeError {
    #[error("stty: {0}")]
    Stty(io::Error),
    #[error("stty -F {port} {baud} raw: {status}")]
    SttyFailed {
        port: String,
        baud: u32,
        status: std::process::ExitStatus,
    },
    #[error("{port}: {source}")]
    Port { port: String, source: io::Error },
    #[error("{0}: not a serial port (not a terminal)")]
    NotASerialPort(String),
    #[error("medium on {listen}: {source}")]
    Medium {
        listen: SocketAddr,
        source: io::Error,
    },
    #[error("the bridge's own connection: {0}")]
    Join(io::Error),
}

/// A medium on `listen` whose frames also go to the air through the gateway on `serial`
/// (and the air's to it); returns the medium and the thread carrying the air's frames.
pub fn bridge(
    serial: &Path,
    baud: u32,
    listen: SocketAddr,
) -> Result<(Medium, JoinHandle<io::Result<()>>), BridgeError> {
    let port_name = || serial.display().to_string();
    let port = std::fs::OpenOptions::new()
        .read(true)
        .write(true)
        .open(serial)
        .map_err(|source| BridgeError::Port {
            port: port_name(),
            source,
        })?;
    // A terminal by what it is, not by its name (`/dev/serial/by-id/...`, `/dev/pts/N`
    // were left in the line mode a terminal starts in, and their baud unset); anything
    // else (a file, `/dev/null`) ended at once, and the gateway said nothing.
    if !std::io::IsTerminal::is_terminal(&port) {
        return Err(BridgeError::NotASerialPort(port_name()));
    }
    let status = std::process::Command::new("stty")
        .arg("-F")
        .arg(serial)
        .args([baud.to_string().as_str(), "raw", "-echo"])
        .status()
        .map_err(BridgeError::Stty)?;
    if !status.success() {
        return Err(BridgeError::SttyFailed {
            port: port_name(),
            baud,
            status,
        });
    }
    let m = Medium::start(Config {
        listen,
        ..Config::default()
    })
    .map_err(|source| BridgeError::Medium { listen, source })?;
    let conn = Conn::join(m.addr(), Peer::Monitor).map_err(BridgeError::Join)?;
    let stream = conn.try_clone_stream().map_err(BridgeError::Join)?;
    let to_air = port.try_clone().map_err(|source| BridgeError::Port {
        port: port_name(),
        source,
    })?;
    let from_medium = stream.try_clone().map_err(BridgeError::Join)?;
    // Medium -> air and air -> medium, each in its own thread; frames only.
    std::thread::spawn(move || forward_frames(from_medium, to_air));
    let up = std::thread::spawn(move || forward_frames(port, stream));
    Ok((m, up))
}

/// Copies the `Link::Frame` messages of `from` to `to` until `from` ends.
fn forward_frames(mut from: impl Read, mut to: impl Write) -> io::Result<()> {
    let mut incoming = Box::new(Deframer::<{ 8 * MAX_LINK }>::resynchronising());
    let mut out = [0u8; MAX_LINK];
    loop {
        let n = from.read(incoming.space())?;
        if n == 0 {
            return Ok(());
        }
        incoming.filled(n);
        loop {
            let body = match incoming.take() {
                Ok(Some(body)) => body,
                Ok(None) => break,
                // Longer than any message (noise on a serial line): a byte dropped.
                Err(_) => continue,
            };
            // Only what a radio could have sent: the medium cuts off a client that sends a
            // longer frame (and with it every client of the gateway).
            if let Ok(Link::Frame(psdu)) = Link::parse(body) {
                if psdu.len() > MAX_PSDU {
                    continue;
                }
                if let Ok(m) = Link::Frame(psdu).emit(&mut out) {
                    to.write_all(&out[..m])?;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::forward_frames;
    use config_schema::wire::medium::{Link, MAX_LINK};

    fn emitted(link: &Link<'_>) -> Vec<u8> {
        let mut buf = [0u8; MAX_LINK];
        let n = link.emit(&mut buf).unwrap();
        buf[..n].to_vec()
    }

    /// What the gateway's serial line carried, as the medium gets it.
    fn forwarded(serial: &[u8]) -> Vec<u8> {
        let mut out = Vec::new();
        forward_frames(serial, &mut out).unwrap();
        out
    }

    /// A frame longer than any PSDU on the serial line is not passed on (the medium cut
    /// off the bridge for it: every client lost the gateway); the next one is.
    #[test]
    fn an_oversize_frame_from_the_serial_line_is_dropped() {
        let good = emitted(&Link::Frame(&[0x41; 20]));
        let serial = [emitted(&Link::Frame(&[0u8; 128])), good.clone()].concat();
        assert_eq!(forwarded(&serial), good);
    }

    /// A stray byte on the serial line (a UART glitch at power-up) before the frames: the
    /// frames after it come through. Its shifted length skipped thousands of bytes of real
    /// traffic, and the gateway heard nothing for minutes.
    #[test]
    fn the_serial_line_finds_its_frames_again_after_a_stray_byte() {
        let frames: Vec<Vec<u8>> = (0..3u8).map(|i| emitted(&Link::Frame(&[i; 12]))).collect();
        for stray in [0x00u8, 0x05, 0xFF] {
            let serial = [vec![stray], frames.concat()].concat();
            assert_eq!(forwarded(&serial), frames.concat(), "{stray:#04x}");
        }
    }
}
