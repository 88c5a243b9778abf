//! The medium's capture: every frame put on the air, as IEEE 802.15.4 with FCS (link type
//! 195), which Wireshark and tshark decode.

use std::fs::File;
use std::io::{self, Write};
use std::path::Path;
use std::time::Duration;

use pcap_file::pcap::{PcapHeader, PcapPacket, PcapWriter};
use pcap_file::DataLink;

/// A pcap file being written.
pub struct PcapLog {
    writer: PcapWriter<Box<dyn Write + Send>>,
    /// A write failed (a full disk): the file ends there, and nothing more is written
    /// after what may be a partial record.
    failed: bool,
}

impl PcapLog {
    /// Creates (truncates) the file and writes the header.
    pub fn create(path: &Path) -> io::Result<PcapLog> {
        PcapLog::over(Box::new(File::create(path)?))
    }

    /// A capture written to `out`, its header first.
    fn over(out: Box<dyn Write + Send>) -> io::Result<PcapLog> {
        let header = PcapHeader {
            datalink: DataLink::IEEE802_15_4,
            ..PcapHeader::default()
        };
        let writer = PcapWriter::with_header(out, header).map_err(io::Error::other)?;
        Ok(PcapLog {
            writer,
            failed: false,
        })
    }

    /// Writes one frame at `at` since the capture started. Unbuffered: the file is complete
    /// whenever the medium stops (a few frames a second do not need a buffer). After a
    /// failed write every later frame is refused too (`Err`), unwritten.
    pub fn write(&mut self, at: Duration, psdu: &[u8]) -> io::Result<()> {
        if self.failed {
            return Err(io::Error::other("an earlier write failed"));
        }
        let packet = PcapPacket::new(at, psdu.len() as u32, psdu);
        let written = self.writer.write_packet(&packet).map(drop);
        self.failed = written.is_err();
        written.map_err(|e| match e {
            pcap_file::PcapError::IoError(e) => e,
            e => io::Error::other(e),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A file system that takes `room` bytes, then is full.
    struct Full {
        room: usize,
    }

    impl Write for Full {
        fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
            if self.room == 0 {
                return Err(io::Error::from(io::ErrorKind::StorageFull));
            }
            let n = buf.len().min(self.room);
            self.room -= n;
            Ok(n)
        }
        fn flush(&mut self) -> io::Result<()> {
            Ok(())
        }
    }

    /// A write that fails is an error, and so is every later one, unwritten: the
    /// medium counts them (`Stats::pcap_unwritten`). Failures were dropped, and a full disk
    /// cut a demo's capture short with nothing said.
    #[test]
    fn a_failed_write_is_an_error_and_so_is_every_later_one() {
        // The header (24 bytes), one 16-byte record header and a 10-byte frame, then 20
        // bytes: the second frame is cut.
        let mut log = PcapLog::over(Box::new(Full { room: 24 + 26 + 20 })).unwrap();
        let at = Duration::from_millis(1);
        assert!(log.write(at, &[0xAA; 10]).is_ok());
        let e = log.write(at, &[0xBB; 10]).unwrap_err();
        assert_eq!(e.kind(), io::ErrorKind::StorageFull);
        assert!(log.write(at, &[0xCC; 1]).is_err());
    }
}
