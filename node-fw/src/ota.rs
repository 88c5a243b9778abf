//! Over-the-air table transfer: pure state machines for the node ([`Receiver`]) and the tool
//! ([`Sender`]), sharing the messages of `config_schema::wire::msg`.
//!
//! ```text
//! tool                                   node
//! ConfigBegin{gen, len, crc, force}  ->  Next{0}         (or Refused(Stale/TooLong))
//! ConfigChunk{gen, offset, data}     ->  Next{first missing byte}
//!   ... up to WINDOW chunks in flight; chunks have fixed places (offset = i * CHUNK_DATA),
//!   so the node stages them in any order and only lost ones are waited for
//! ConfigEnd{gen}                     ->  Staged          (or Refused(Crc/Invalid/Pin/Flash))
//! ```
//! Every message is answered, and every answer says where the node is, so the tool resends
//! whatever was lost. Nothing is staged before the whole transfer's CRC-32C matches, the table
//! decodes and validates, and every pin it names is on the board; a transfer that stops
//! anywhere leaves the old table running. A staged table runs only on the switch-over
//! (`Message::Switch`, the node's part: `crate::node`).

use config_schema::blob::TRANSFER_CRC;
use config_schema::limits::MAX_BLOB;
use config_schema::link_keys::decode_deployment;
use config_schema::wire::msg::{ConfigReply, Message, Refusal, CHUNK_DATA};

/// Chunks the tool keeps in flight.
pub const WINDOW: usize = 4;
/// Tool-side retransmission timeout, counted from when the tool's frames are off the air
/// ([`Sender::on_air`]): the node's answer (its airtime, a few ms), the node's handling
/// and the host's scheduling of both ends.
pub const RTO_MS: u64 = 40;
/// What the end of a transfer may take on top: the node decodes, validates and persists
/// the table (a flash page erase and write on a real node: tens of ms).
pub const PERSIST_MS: u64 = 200;
/// Times the tool starts a transfer over because the node lost it.
pub const MAX_RESTARTS: u8 = 3;
/// Tool-side timeouts without progress before it gives up.
pub const GIVE_UP_AFTER: u8 = 25;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Transfer {
    generation: u32,
    len: u16,
    crc: u32,
    /// Bit i: chunk i (bytes `i * CHUNK_DATA ..`) is staged.
    have: u64,
    /// Bytes before the first missing chunk.
    received: u16,
}

/// Chunks of the largest blob: one bit each in `Transfer::have`.
const MAX_CHUNKS: usize = MAX_BLOB.div_ceil(CHUNK_DATA);
const _: () = assert!(MAX_CHUNKS <= 64);

impl Transfer {
    fn chunks(&self) -> usize {
        usize::from(self.len).div_ceil(CHUNK_DATA)
    }

    /// Length chunk `index` must have.
    fn chunk_len(&self, index: usize) -> usize {
        (usize::from(self.len) - index * CHUNK_DATA).min(CHUNK_DATA)
    }

    fn update_received(&mut self) {
        let first_missing = (!self.have).trailing_zeros() as usize;
        self.received = (first_missing * CHUNK_DATA).min(usize::from(self.len)) as u16;
    }
}

/// Where the node puts a transfer's chunks as they come, and reads the whole blob back
/// from (contiguous) to check and persist it. [`RamStaging`] is a RAM buffer (the host,
/// tests); an MCU board puts them in a flash page of its own, memory-mapped, so that no
/// blob is held in RAM (node-fw/boards: `Staging` of the nRF52840 and QEMU boards).
pub trait Staging {
    /// Makes the area ready for a new transfer (a flash page erased); `false`: it failed.
    fn clear(&mut self) -> bool;
    /// Puts `data` (at most `CHUNK_DATA` bytes) at `offset` (a multiple of `CHUNK_DATA`,
    /// each place put once after a clear); `false`: it failed.
    fn put(&mut self, offset: usize, data: &[u8]) -> bool;
    /// The first `len` bytes (empty if `len` is past the area).
    fn get(&self, len: usize) -> &[u8];
}

/// A transfer staged in RAM: [`MAX_BLOB`] bytes.
#[derive(Debug, Clone)]
pub struct RamStaging([u8; MAX_BLOB]);

impl RamStaging {
    pub const fn new() -> Self {
        RamStaging([0; MAX_BLOB])
    }
}

impl Default for RamStaging {
    fn default() -> Self {
        Self::new()
    }
}

impl Staging for RamStaging {
    fn clear(&mut self) -> bool {
        true
    }
    fn put(&mut self, offset: usize, data: &[u8]) -> bool {
        match self.0.get_mut(offset..offset + data.len()) {
            Some(dst) => {
                copy(dst, data);
                true
            }
            None => false,
        }
    }
    fn get(&self, len: usize) -> &[u8] {
        self.0.get(..len).unwrap_or(&[])
    }
}

impl<S: Staging + ?Sized> Staging for &mut S {
    fn clear(&mut self) -> bool {
        (**self).clear()
    }
    fn put(&mut self, offset: usize, data: &[u8]) -> bool {
        (**self).put(offset, data)
    }
    fn get(&self, len: usize) -> &[u8] {
        (**self).get(len)
    }
}

/// A transfer taken whole: which table it was.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Taken {
    generation: u32,
    len: u16,
    crc: u32,
}

/// The node's side: stages one incoming blob in its [`Staging`].
#[derive(Debug, Clone)]
pub struct Receiver<S = RamStaging> {
    transfer: Option<Transfer>,
    /// The last transfer taken whole, until the board says whether it persisted it.
    taken: Option<Taken>,
    /// The table staged, as far as this receiver knows it (`None` after a boot, or when
    /// persisting failed): a begin of the staged generation is answered `Staged` only if
    /// it offers this table; another table of that generation replaces it.
    staged: Option<Taken>,
    /// Bit n: the board has pin n.
    board_pins: u64,
    staging: S,
}

impl Default for Receiver {
    fn default() -> Self {
        Self::new()
    }
}

/// What the node does with a config message.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Outcome {
    /// Answer with this reply.
    Reply(ConfigReply),
    /// The blob is complete, its CRC matches, it decodes and validates and its pins are on
    /// the board: persist [`Receiver::blob`]`(len)` to the inactive slot as staged and
    /// answer `Staged` (or `Refused(Flash)` if persisting failed).
    Stage {
        generation: u32,
        /// Length of the staged blob.
        len: usize,
    },
}

impl Receiver {
    /// A receiver that takes any pin a table may name (`0..MAX_PINS`), staging in RAM.
    pub const fn new() -> Self {
        Self::for_board(u64::MAX)
    }

    /// A receiver on a board with pins `board_pins` (bit n: the board has pin n), staging
    /// in RAM: a table naming another pin is refused with `Refusal::Pin`.
    pub const fn for_board(board_pins: u64) -> Self {
        Receiver::staging_in(board_pins, RamStaging::new())
    }
}

impl<S: Staging> Receiver<S> {
    /// A receiver on a board with pins `board_pins`, staging in `staging`.
    pub const fn staging_in(board_pins: u64, staging: S) -> Self {
        Receiver {
            transfer: None,
            taken: None,
            staged: None,
            board_pins,
            staging,
        }
    }

    /// The board persisted the last transfer taken whole ([`Outcome::Stage`]) as the staged
    /// table (`ok`), or failed to (what is staged is then unknown here).
    pub fn persisted(&mut self, ok: bool) {
        let taken = self.taken.take();
        self.staged = if ok { taken } else { None };
    }

    /// The staged table is gone (its activation failed, its slot revoked): a push of it
    /// again is staged again, not answered `Staged` at once.
    pub fn unstaged(&mut self) {
        self.staged = None;
    }

    /// The generation being received, if a transfer is in progress.
    pub fn receiving(&self) -> Option<u32> {
        self.transfer.map(|t| t.generation)
    }

    /// The blob of the last completed transfer (what `Stage` is to persist).
    pub fn blob(&self, len: usize) -> &[u8] {
        self.staging.get(len)
    }

    /// Forgets any transfer in progress.
    pub fn abort(&mut self) {
        self.transfer = None;
    }

    /// Handles a config message; `running` is the generation of the running table (0 when
    /// unconfigured), `staged` the one staged (0: none). Other messages are answered with
    /// `None`.
    pub fn on_message(&mut self, msg: &Message<'_>, running: u32, staged: u32) -> Option<Outcome> {
        // The last answer to a transfer that is done: activated (running) or staged.
        let done = |generation: u32| {
            if generation == staged && staged != 0 {
                Some(ConfigReply::Staged)
            } else if generation == running && running != 0 {
                Some(ConfigReply::Activated)
            } else {
                None
            }
        };
        let reply = |r| Some(Outcome::Reply(r));
        match *msg {
            Message::ConfigBegin {
                generation,
                len,
                crc,
                force,
            } => {
                if let Some(t) = self
                    .transfer
                    .filter(|t| (t.generation, t.len, t.crc) == (generation, len, crc))
                {
                    // A repeated begin (its answer lost): say where we are. Another
                    // table's begin (an edited robot pushed again at that generation)
                    // starts over below.
                    return reply(ConfigReply::Next { next: t.received });
                }
                let offered = Taken {
                    generation,
                    len,
                    crc,
                };
                if generation == staged && staged != 0 && !force && self.staged == Some(offered) {
                    // Staged already (its answer was lost, or the tool pushes again).
                    return reply(ConfigReply::Staged);
                }
                // Another table of the staged generation (or one this receiver cannot tell
                // apart since a boot) is taken again: it replaces the staged one.
                if generation <= running && !force {
                    return reply(ConfigReply::Refused(Refusal::Stale { running }));
                }
                // An older generation (a late or replayed begin) does not replace a newer
                // transfer in progress.
                if let Some(t) = self
                    .transfer
                    .filter(|t| generation < t.generation && !force)
                {
                    return reply(ConfigReply::Refused(Refusal::Superseded {
                        transfer: t.generation,
                    }));
                }
                if usize::from(len) > MAX_BLOB {
                    return reply(ConfigReply::Refused(Refusal::TooLong));
                }
                self.transfer = None;
                if !self.staging.clear() {
                    return reply(ConfigReply::Refused(Refusal::Flash));
                }
                self.transfer = Some(Transfer {
                    generation,
                    len,
                    crc,
                    have: 0,
                    received: 0,
                });
                reply(ConfigReply::Next { next: 0 })
            }
            Message::ConfigChunk {
                generation,
                offset,
                data,
            } => {
                let Some(t) = self
                    .transfer
                    .as_mut()
                    .filter(|t| t.generation == generation)
                else {
                    // A late copy of a chunk of the table now staged or running: it is in.
                    if let Some(r) = done(generation) {
                        return reply(r);
                    }
                    return reply(ConfigReply::Refused(Refusal::OutOfSequence));
                };
                // Chunks may arrive in any order; each has a fixed place and length.
                let offset = usize::from(offset);
                let index = offset / CHUNK_DATA;
                if offset % CHUNK_DATA == 0
                    && index < t.chunks()
                    && data.len() == t.chunk_len(index)
                    && t.have & (1 << index) == 0
                {
                    // Each place is put once (a flash word is written once per erase).
                    if !self.staging.put(offset, data) {
                        self.transfer = None;
                        return reply(ConfigReply::Refused(Refusal::Flash));
                    }
                    t.have |= 1 << index;
                    t.update_received();
                }
                reply(ConfigReply::Next { next: t.received })
            }
            Message::ConfigEnd { generation } => {
                let Some(t) = self.transfer.filter(|t| t.generation == generation) else {
                    // The end of the transfer now staged or running: its answer was lost.
                    if let Some(r) = done(generation) {
                        return reply(r);
                    }
                    return reply(ConfigReply::Refused(Refusal::OutOfSequence));
                };
                if t.received != t.len {
                    return reply(ConfigReply::Next { next: t.received });
                }
                self.transfer = None;
                let blob = self.blob(usize::from(t.len));
                if TRANSFER_CRC.checksum(blob) != t.crc {
                    return reply(ConfigReply::Refused(Refusal::Crc));
                }
                let board = self.board_pins;
                match decode_deployment(blob) {
                    Ok(d) if d.table.generation == generation => match d.table.missing_pin(board) {
                        Some(pin) => reply(ConfigReply::Refused(Refusal::Pin { pin, board })),
                        None => {
                            self.taken = Some(Taken {
                                generation,
                                len: t.len,
                                crc: t.crc,
                            });
                            Some(Outcome::Stage {
                                generation,
                                len: usize::from(t.len),
                            })
                        }
                    },
                    _ => reply(ConfigReply::Refused(Refusal::Invalid)),
                }
            }
            _ => None,
        }
    }
}

/// Where the tool's transfer stands.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Progress {
    /// Still sending.
    Busy,
    /// The node staged the table (or runs it already).
    Done,
    /// The node refused it.
    Refused(Refusal),
    /// The node stopped answering.
    GaveUp,
}

/// Counters of one transfer.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct TransferStats {
    pub frames: u32,
    pub retries: u32,
    pub bytes: u32,
}

/// The tool's side of one transfer to one node.
#[derive(Debug, Clone)]
pub struct Sender<'b> {
    blob: &'b [u8],
    generation: u32,
    force: bool,
    /// Acknowledged bytes (the node's `next`); `None` until the begin is answered.
    acked: Option<u16>,
    /// Bytes sent at least once.
    sent: u16,
    ended: bool,
    progress: Progress,
    deadline: u64,
    /// When the tool's frames sent so far are off the air ([`Sender::on_air`]).
    air_clear: u64,
    timeouts: u8,
    /// Timeouts the node answered with a challenge ([`Sender::challenged`]).
    challenges: u8,
    /// Times the node lost the transfer (`OutOfSequence`) and it started over.
    restarts: u8,
    stats: TransferStats,
}

impl<'b> Sender<'b> {
    /// A transfer of `blob` (an encoded table of `generation`).
    pub fn new(blob: &'b [u8], generation: u32, force: bool) -> Self {
        Sender {
            blob,
            generation,
            force,
            acked: None,
            sent: 0,
            ended: false,
            progress: Progress::Busy,
            deadline: 0,
            air_clear: 0,
            timeouts: 0,
            challenges: 0,
            restarts: 0,
            stats: TransferStats::default(),
        }
    }

    pub fn progress(&self) -> Progress {
        self.progress
    }

    pub fn stats(&self) -> TransferStats {
        self.stats
    }

    /// Bytes the node has acknowledged.
    pub fn acked(&self) -> usize {
        usize::from(self.acked.unwrap_or(0))
    }

    fn chunk(&self, offset: u16) -> Message<'b> {
        let start = usize::from(offset).min(self.blob.len());
        let end = (start + CHUNK_DATA).min(self.blob.len());
        Message::ConfigChunk {
            generation: self.generation,
            offset,
            data: &self.blob[start..end],
        }
    }

    fn send(&mut self, msg: Message<'b>, send: &mut impl FnMut(Message<'b>)) {
        if let Message::ConfigChunk { data, .. } = &msg {
            self.stats.bytes += data.len() as u32;
        }
        crate::count(&mut self.stats.frames);
        send(msg);
    }

    /// Sends the window from the acknowledged point: chunks not yet sent, or (`resend`)
    /// all of them.
    fn fill(&mut self, resend: bool, send: &mut impl FnMut(Message<'b>)) {
        let Some(acked) = self.acked else {
            let crc = TRANSFER_CRC.checksum(self.blob);
            let begin = Message::ConfigBegin {
                generation: self.generation,
                len: self.blob.len() as u16,
                crc,
                force: self.force,
            };
            self.send(begin, send);
            return;
        };
        let total = self.blob.len() as u16;
        if acked >= total {
            if resend || !self.ended {
                self.ended = true;
                self.send(
                    Message::ConfigEnd {
                        generation: self.generation,
                    },
                    send,
                );
            }
            return;
        }
        let window_end = (usize::from(acked) + WINDOW * CHUNK_DATA).min(self.blob.len()) as u16;
        let mut offset = if resend { acked } else { self.sent.max(acked) };
        while offset < window_end {
            let msg = self.chunk(offset);
            self.send(msg, send);
            offset = (usize::from(offset) + CHUNK_DATA).min(self.blob.len()) as u16;
        }
        self.sent = self.sent.max(offset);
    }

    /// Starts the transfer (sends the begin).
    pub fn start(&mut self, now: u64, mut send: impl FnMut(Message<'b>)) {
        if self.blob.len() > usize::from(u16::MAX) {
            self.progress = Progress::Refused(Refusal::TooLong);
            return;
        }
        self.fill(false, &mut send);
        self.arm(now);
    }

    /// The retransmission deadline from `from`: a round trip, and the persisting time once
    /// the end is out.
    fn rto(&self) -> u64 {
        RTO_MS + if self.ended { PERSIST_MS } else { 0 }
    }

    /// The deadline of what is outstanding: a timeout after now, or after the air is
    /// clear of the tool's frames sent so far (this transfer's among them).
    fn arm(&mut self, now: u64) {
        self.deadline = now.max(self.air_clear) + self.rto();
    }

    /// The frames sent so far (to every node: the air is shared) are off the air at
    /// `clear` at the earliest: no answer can be late before `clear` plus the timeout.
    pub fn on_air(&mut self, clear: u64) {
        self.air_clear = self.air_clear.max(clear);
        if self.progress == Progress::Busy {
            self.deadline = self.deadline.max(clear + self.rto());
        }
    }

    /// A reply from the node.
    pub fn on_reply(
        &mut self,
        generation: u32,
        reply: ConfigReply,
        now: u64,
        mut send: impl FnMut(Message<'b>),
    ) {
        if generation != self.generation || self.progress != Progress::Busy {
            return;
        }
        match reply {
            ConfigReply::Next { next } => {
                if next as usize > self.blob.len() {
                    return;
                }
                let progressed = self.acked.is_none_or(|a| next > a);
                if !progressed {
                    return;
                }
                self.acked = Some(next);
                self.timeouts = 0;
                self.fill(false, &mut send);
                self.arm(now);
            }
            // The node has this generation staged (this transfer, or one before it: a
            // repeated push).
            ConfigReply::Staged => self.progress = Progress::Done,
            // Running it (a node that switched already).
            ConfigReply::Activated => {
                if self.ended {
                    self.progress = Progress::Done;
                }
            }
            // Answers of the switch-over, not of a transfer.
            ConfigReply::Armed { .. }
            | ConfigReply::Busy
            | ConfigReply::Disarmed
            | ConfigReply::Confirmed => {}
            // Answers to chunks sent before a restart, while the begin is not answered yet.
            ConfigReply::Refused(Refusal::OutOfSequence) if self.acked.is_none() => {}
            // The node does not know this transfer (it restarted, or began another):
            // start over, a few times.
            ConfigReply::Refused(Refusal::OutOfSequence) if self.restarts < MAX_RESTARTS => {
                self.restarts += 1;
                self.acked = None;
                self.sent = 0;
                self.ended = false;
                self.timeouts = 0;
                self.fill(false, &mut send);
                self.arm(now);
            }
            ConfigReply::Refused(why) => self.progress = Progress::Refused(why),
        }
    }

    /// Resends after a timeout.
    pub fn poll(&mut self, now: u64, mut send: impl FnMut(Message<'b>)) {
        if self.progress != Progress::Busy || now < self.deadline {
            return;
        }
        self.timeouts += 1;
        if self.timeouts > GIVE_UP_AFTER {
            self.progress = Progress::GaveUp;
            return;
        }
        let before = self.stats.frames;
        self.fill(true, &mut send);
        self.stats.retries += self.stats.frames - before;
        self.arm(now);
    }

    /// The node answered the last message with a challenge (a secured node that does not
    /// know the tool's frame counter yet; the tool answered it and resent): the node is
    /// there, so the timeout does not count toward giving up. A lost answer costs a whole
    /// round (the node challenges again only on a retry, at most once per
    /// `node::CHALLENGE_MS`), so on a lossy channel this may take many rounds; a node that
    /// never takes an answer is given up on after [`GIVE_UP_AFTER`] of them more.
    pub fn challenged(&mut self) {
        if self.challenges < GIVE_UP_AFTER && self.timeouts > 0 {
            self.challenges += 1;
            self.timeouts -= 1;
        }
    }

    /// When [`Sender::poll`] next has work.
    pub fn deadline(&self) -> u64 {
        self.deadline
    }
}

/// `dst = src` (as long: the caller sliced `dst` to `src`'s length). A loop of its own, not
/// `copy_from_slice`: where the optimizer leaves that out of line its panic location (this
/// file's path) stays in the image, in the secured image and not the unsecured one, and
/// what security costs would move with the checkout's path (bench/footprint.sh).
#[inline(never)]
fn copy(dst: &mut [u8], src: &[u8]) {
    dst.iter_mut().zip(src).for_each(|(d, s)| *d = *s);
}
