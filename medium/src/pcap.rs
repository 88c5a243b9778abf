//! The medium's capture: every frame put on the air, as IEEE 802.15.4 with FCS (link type
//! 195), which Wireshark and tshark decode.

use std::fs::File;
use std::io;
use std::path::Path;
use std::time::Duration;

use pcap_file::pcap::{PcapHeader, PcapPacket, PcapWriter};
use pcap_file::DataLink;

/// A pcap file being written.
pub struct PcapLog {
    writer: PcapWriter<File>,
}

impl PcapLog {
    /// Creates (truncates) the file and writes the header.
    pub fn create(path: &Path) -> io::Result<PcapLog> {
        let file = File::create(path)?;
        let header = PcapHeader {
            datalink: DataLink::IEEE802_15_4,
            ..PcapHeader::default()
        };
        let writer = PcapWriter::with_header(file, header).map_err(io::Error::other)?;
        Ok(PcapLog { writer })
    }

    /// Writes one frame at `at` since the capture started. Unbuffered: the file is complete
    /// whenever the medium stops (a few frames a second do not need a buffer).
    pub fn write(&mut self, at: Duration, psdu: &[u8]) {
        let packet = PcapPacket::new(at, psdu.len() as u32, psdu);
        let _ = self.writer.write_packet(&packet);
    }
}
