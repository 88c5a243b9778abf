//! The runtime's radio on the nRF52840's IEEE 802.15.4 radio. The hardware computes the FCS
//! on transmit and checks it on receive (frames that fail it are dropped here); the runtime
//! deals in MPDUs (frames without the FCS), so they go to and come from the radio as they
//! are: no CRC in software.

use config_schema::wire::mac::{MAX_MPDU, MAX_PSDU};
use embassy_nrf::radio::ieee802154::{Packet, Radio};
use embassy_nrf::radio::Error;
use embassy_time::{Duration, Timer};
use node_fw::runtime::Received;

/// Clear-channel assessments before a frame is given up (backing off 320 us, 640 us, ...).
const CCA_ATTEMPTS: usize = 4;
/// The back-off after the n-th busy channel: 320 us x 2^n, in ticks at compile time (no
/// 64-bit division in the image).
const BACKOFF: [Duration; CCA_ATTEMPTS] = {
    let mut b = [Duration::from_ticks(0); CCA_ATTEMPTS];
    let mut n = 0;
    while n < CCA_ATTEMPTS {
        b[n] = Duration::from_micros(320 << n);
        n += 1;
    }
    b
};

pub struct NrfRadio {
    pub radio: Radio<'static>,
    pub packet: Packet,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SendError {
    /// Not an MPDU (longer than 125 bytes).
    Length,
    /// The channel stayed busy.
    ChannelBusy,
}

impl node_fw::runtime::Radio for NrfRadio {
    /// Only sending fails; receiving never does (the runtime stops only if the radio is gone).
    type Error = SendError;

    async fn send(&mut self, mpdu: &[u8]) -> Result<(), SendError> {
        if mpdu.len() > MAX_MPDU || mpdu.len() > usize::from(Packet::CAPACITY) {
            return Err(SendError::Length);
        }
        self.packet.copy_from_slice(mpdu);
        for backoff in BACKOFF {
            match self.radio.try_send(&mut self.packet).await {
                Ok(()) => return Ok(()),
                Err(Error::ChannelInUse) => Timer::after(backoff).await,
                Err(_) => break,
            }
        }
        Err(SendError::ChannelBusy)
    }

    async fn receive(&mut self, buf: &mut [u8; MAX_PSDU]) -> Result<Received, SendError> {
        loop {
            if self.radio.receive(&mut self.packet).await.is_err() {
                continue; // bad FCS: as if never heard
            }
            let n = self.packet.len() as usize;
            if let Some(dst) = buf.get_mut(..n).filter(|_| n <= MAX_MPDU) {
                dst.copy_from_slice(&self.packet);
                return Ok(Received::Mpdu(n));
            }
        }
    }
}
