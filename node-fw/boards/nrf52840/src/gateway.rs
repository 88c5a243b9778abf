//! Gateway mode: the node bridges its radio to a serial line in the medium's framing (u16 LE
//! length + postcard `Link`, as on the QEMU board's UART). Every frame the radio hears goes
//! out as `Link::Frame` (FCS appended: the serial line carries PSDUs, the radio MPDUs);
//! every `Link::Frame` that comes in is transmitted if its FCS matches.
//! `config-tool gateway --serial DEV` puts it on a medium, where `push`, `scan`, `status`
//! and `monitor` reach the real nodes in range.
//!
//! Serial: UARTE0 on P0.08 (RX) / P0.06 (TX) at 1 Mbaud, the DK's J-Link virtual COM port.

use config_schema::wire::mac::{strip_fcs, MAX_PSDU};
use config_schema::wire::medium::{Deframer, Link, MAX_LINK};
use embassy_futures::select::{select, Either};
use embassy_nrf::buffered_uarte::{BufferedUarteRx, BufferedUarteTx};
use node_fw::runtime::{psdu_of, Radio as _, Received};

use crate::radio::NrfRadio;

/// Bytes of the serial stream not yet parsed: survives a cancelled read.
struct Reader {
    incoming: Deframer<{ 2 * MAX_LINK }>,
}

impl Reader {
    /// Waits until a whole message is buffered ([`Deframer::next`] then returns it).
    /// Bytes that are not the framing (noise on the line) are dropped.
    async fn wait(&mut self, rx: &mut BufferedUarteRx<'_>) {
        loop {
            match self.incoming.complete() {
                Ok(true) => return,
                // Skipped; a whole message may be buffered behind it.
                Err(_) => continue,
                Ok(false) => {}
            }
            let Ok(bytes) = rx.fill_buf().await else {
                continue;
            };
            let n = self.incoming.push(bytes);
            rx.consume(n);
        }
    }
}

async fn write_all(tx: &mut BufferedUarteTx<'_>, mut bytes: &[u8]) {
    while !bytes.is_empty() {
        match tx.write(bytes).await {
            Ok(n) => bytes = &bytes[n..],
            Err(_) => return,
        }
    }
}

pub async fn run(
    mut radio: NrfRadio,
    mut rx: BufferedUarteRx<'static>,
    mut tx: BufferedUarteTx<'static>,
) -> ! {
    // A serial line can lose or gain a byte (a glitch as the host opens the port): the
    // framing finds the next message again at once.
    let mut reader = Reader {
        incoming: Deframer::resynchronising(),
    };
    let mut mpdu = [0u8; MAX_PSDU];
    let mut out = [0u8; MAX_LINK];
    let (mut to_air, mut from_air) = (0u32, 0u32);
    loop {
        match select(reader.wait(&mut rx), radio.receive(&mut mpdu)).await {
            Either::First(()) => {
                let body = reader.incoming.take().ok().flatten().unwrap_or_default();
                let frame = match Link::parse(body) {
                    Ok(Link::Frame(psdu)) => strip_fcs(psdu).ok(),
                    _ => None,
                };
                if let Some(frame) = frame {
                    if radio.send(frame).await.is_ok() {
                        to_air += 1;
                        if to_air.is_multiple_of(100) {
                            defmt::info!("gateway: {=u32} frames to the air", to_air);
                        }
                    }
                }
            }
            Either::Second(Ok(Received::Mpdu(n))) => {
                let psdu = mpdu.get(..n).and_then(psdu_of).unwrap_or_default();
                if let Ok(m) = Link::Frame(&psdu).emit(&mut out) {
                    write_all(&mut tx, &out[..m]).await;
                    from_air += 1;
                    if from_air.is_multiple_of(100) {
                        defmt::info!("gateway: {=u32} frames from the air", from_air);
                    }
                }
            }
            Either::Second(Ok(Received::Dropped) | Err(_)) => {}
        }
    }
}
