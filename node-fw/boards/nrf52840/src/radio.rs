//! The runtime's radio on the nRF52840's IEEE 802.15.4 radio. The hardware computes the FCS
//! on transmit and checks it on receive (frames that fail it are dropped here); the runtime
//! deals in PSDUs with the FCS, so it is cut off before sending and appended on receipt.

use config_schema::wire::mac::{FCS, MAX_PSDU};
use embassy_nrf::radio::ieee802154::{Packet, Radio};
use embassy_nrf::radio::Error;
use embassy_time::{Duration, Timer};

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
    /// Not a PSDU (shorter than the FCS or longer than 127 bytes).
    Length,
    /// The channel stayed busy.
    ChannelBusy,
}

impl node_fw::runtime::Radio for NrfRadio {
    /// Only sending fails; receiving never does (the runtime stops only if the radio is gone).
    type Error = SendError;

    async fn send(&mut self, psdu: &[u8]) -> Result<(), SendError> {
        let body = psdu
            .len()
            .checked_sub(2)
            .and_then(|n| psdu.get(..n))
            .filter(|b| b.len() <= usize::from(Packet::CAPACITY))
            .ok_or(SendError::Length)?;
        self.packet.copy_from_slice(body);
        for backoff in BACKOFF {
            match self.radio.try_send(&mut self.packet).await {
                Ok(()) => return Ok(()),
                Err(Error::ChannelInUse) => Timer::after(backoff).await,
                Err(_) => break,
            }
        }
        Err(SendError::ChannelBusy)
    }

    async fn receive(&mut self, buf: &mut [u8; MAX_PSDU]) -> Result<usize, SendError> {
        loop {
            if self.radio.receive(&mut self.packet).await.is_err() {
                continue; // bad FCS: as if never heard
            }
            let n = self.packet.len() as usize;
            if n + 2 > MAX_PSDU {
                continue;
            }
            buf[..n].copy_from_slice(&self.packet);
            let fcs = FCS.checksum(&buf[..n]).to_le_bytes();
            buf[n..n + 2].copy_from_slice(&fcs);
            return Ok(n + 2);
        }
    }
}
