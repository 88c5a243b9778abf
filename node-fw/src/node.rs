//! The whole node as one pure state machine: frames in, frames and pin levels out.
//!
//! [`NodeCore`] owns the running table and the engine state, one reliable link per peer each
//! way, the OTA receiver, the timers and the counters. A board (the Embassy runtime, the
//! host node, a test) feeds it received PSDUs, input pin levels and the time, performs the
//! [`Io`] it asks for, and persists a new table when asked, before the node switches to it.

use config_schema::limits::{MAX_PEERS, MAX_TIMERS};
use config_schema::link_keys::{Deployment, LinkKeys};
use config_schema::wire::mac::{self, Frame, Header, BROADCAST, MAX_MPDU, MAX_PSDU};
use config_schema::wire::msg::{
    Announce, Command, ConfigReply, Counters, LinkMessage, Message, Refusal, RuntimeCounters,
    SecurityCounters, SecurityReport, Status, SwitchStep,
};
use config_schema::wire::security::link::{self as sealed, SealedLink};
use config_schema::wire::security::{self, ext_addr, replay::ReplayGuard, AuxRepr, Opened};
use config_schema::{Publication, Table, TableId};
use heapless::Vec;

use crate::alarms::{Alarms, Seen};
use crate::cipher::NodeCipher;
use crate::ecc::{Effects, Engine, EngineState, Fault, Index};
use crate::epoch::Epochs;
use crate::link::{self, LinkState};
use crate::ota::{self, Outcome, RamStaging, Staging as StagingArea};
use crate::peer_security::{self, PeerSecurity, Pending, Verdict};
use crate::provision::ManagementKey;
use crate::restart;
use crate::switch::{self, SwitchOver};

/// Reported in announcements and status.
pub const FIRMWARE_VERSION: u16 = 1;
/// Announcement period while unconfigured.
pub const ANNOUNCE_MS: u64 = 1000;
/// The PAN id of configuration and command traffic (any node, any robot).
pub const CONFIG_PAN: u16 = 0xFFFF;

/// What the node does to the world.
pub trait Io {
    /// Transmit a PSDU (FCS included): a harness on a medium that carries the FCS.
    fn transmit(&mut self, psdu: &[u8]);
    /// Transmit an MPDU (no FCS: the radio edge appends it, `mac::append_fcs`, or the
    /// radio does in hardware). The core sends every frame through this; the default
    /// appends the FCS here and hands the PSDU to [`Io::transmit`], a board's radio path
    /// takes the MPDU as it is.
    fn transmit_mpdu(&mut self, mpdu: &[u8]) {
        let mut psdu = [0u8; MAX_PSDU];
        let Some(body) = psdu.get_mut(..mpdu.len()) else {
            return;
        };
        body.copy_from_slice(mpdu);
        if let Ok(n) = mac::append_fcs(&mut psdu, mpdu.len()) {
            self.transmit(psdu.get(..n).unwrap_or(&[]));
        }
    }
    /// Drive board pin `pin` to `level`.
    fn set_pin(&mut self, pin: u8, level: bool);
    /// The node runs table generation `generation` from now on (at boot and at every
    /// activation, before any pin the table drives): a board on the simulated medium tells
    /// the plant, whose trace then says under which generation each step ran.
    fn running(&mut self, _generation: u32) {}
    /// What the board's runtime counted, for status (a board without a runtime: zeros).
    fn runtime_counters(&self) -> RuntimeCounters {
        RuntimeCounters::default()
    }
    /// The frame counter for the next secured frame: never handed out before, whatever
    /// power cuts came between (`crate::frame_counter`). `None` (exhausted, the flash
    /// failed, or a board without one): the frame is not sent, and counted.
    fn next_frame_counter(&mut self) -> Option<u32> {
        None
    }
}

/// The key index of the management key in the auxiliary security header.
pub const MANAGEMENT_KEY_INDEX: u8 = 0;
/// Senders on the config PAN whose last frame counter a node remembers (the tool, and a
/// few spare tool addresses); a new one past these is refused, never one forgotten. As many
/// as a table has peers: the replay guard and challenge list of both are then one type, one
/// copy of their code (132 B of the nRF52840 image for 128 B of RAM).
pub const MANAGEMENT_SENDERS: usize = MAX_PEERS;
/// A secured node answers an unsecured broadcast `Identify` (a scan cannot be secured
/// with every node's key) at most once per this many ms: the answer is secured and spends
/// a frame counter, so a flood must not use the counter up.
pub const OPEN_IDENTIFY_MS: u64 = ANNOUNCE_MS;
/// A node sends at most one `Challenge` per this many ms (each spends a frame counter:
/// a flood of replays must not use it up).
pub const CHALLENGE_MS: u64 = 50;
/// Commands that act whose (sender, id) a node remembers, to answer a repeat without
/// running it again: eight, over every sender (a tool's command is resent every 150 ms
/// until it is answered; eight others that act would have to come in between).
pub const RECENT_COMMANDS: usize = 8;
/// How long without a command that acts makes a node forget the ones it remembers: six
/// times the 5 s a tool resends one for. After it, a (sender, id) remembered is a new
/// command (a new run of the tool drew the id again: ids are 16 bits).
pub const REPEAT_MS: u32 = 30_000;

/// A transfer waiting to be staged in flash: its blob is in the OTA buffer (decoded and
/// validated already).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Staging {
    generation: u32,
    len: usize,
    from: u16,
}

/// What the node needs of its flash. The board does it, then answers with
/// [`NodeCore::staged`] or [`NodeCore::activated`], before it hands the node another frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FlashRequest<'a> {
    /// Persist this transfer (a table blob and its key block) in the slot not running, as
    /// staged: checked, not running.
    Stage(&'a [u8]),
    /// Make the staged slot the boot table (`trial`: activated, not confirmed), read it
    /// back and hand it to [`NodeCore::activated`].
    Activate { trial: bool },
    /// Roll back: revoke the running slot, read the previous one back and hand it to
    /// [`NodeCore::activated`].
    Rollback,
    /// Confirm the running slot (on trial), then [`NodeCore::confirmed`].
    Confirm,
    /// Count one more boot in the board's boot counter, then [`NodeCore::boot_counted`]:
    /// the node has taken most of the link epochs its boot count reserves, and the next
    /// boot must start above them ([`crate::epoch`]).
    CountBoot,
}

/// `key`, if the image has frame security ([`crate::FRAME_SECURITY`]: without it every
/// secured path is dead code and the crypto is not linked).
#[inline(always)]
fn gated(key: &Option<ManagementKey>) -> Option<&ManagementKey> {
    key.as_ref().filter(|_| crate::FRAME_SECURITY)
}

/// The generic node, staging pushed tables in `S` ([`ota::RamStaging`]: a RAM buffer of
/// its own; an MCU board's flash page: [`NodeCore::staging_in`]).
pub struct NodeCore<S = RamStaging> {
    /// The node's address, frame numbering, counters, keys: what sending needs.
    radio: Radio,
    /// Bit n: the board has pin n. A table naming another pin is refused.
    board_pins: u64,
    table: Option<Table>,
    /// The running table's identity on the air (its blob's CRC; `NONE` without a table).
    table_id: TableId,
    /// The running table's index, built once when it was installed.
    index: Option<Index>,
    state: Option<EngineState>,
    timers: [Option<u64>; MAX_TIMERS],
    senders: Senders,
    /// (peer address, link) for each of the table's peers, by peer index.
    receivers: Vec<(u16, link::Receiver), MAX_PEERS>,
    ota: ota::Receiver<S>,
    staging: Option<Staging>,
    /// The staged generation and the switch-over to it.
    switch: SwitchOver,
    /// The newest link epoch, and how far the boot counter reserves them.
    epochs: Epochs,
    /// Bit i: the last `Reset` re-established the link to peer i.
    restarted: u8,
    /// Cycles this node's START began at its idle point and that ended with the node back
    /// at it (`Status::cycles`), and whether one is under way.
    cycles: u8,
    cycle_open: bool,
    /// The table's boot event is still to be raised (the node booted with a table).
    boot_pending: bool,
    /// The greetings still to send after a boot, on a robot without link keys.
    greetings: restart::Greetings,
    /// The running table is the one the node booted with: its greetings say it booted
    /// ([`restart::GREETING`]; a new table's greetings only ask for a floor).
    booted: bool,
    /// The peers' restarts heard.
    restarts: restart::Heard,
    next_announce: u64,
    /// The (sender, id) of the last commands run that act (START, RESET, HOME, ACK), oldest
    /// first: a repeat is answered, not run again. Several per sender: runs of the tool at
    /// once share its address, and one may resend its command after another's came in
    /// between. Forgotten after [`REPEAT_MS`] without one (`commands_at`: when the last
    /// came, ms since boot).
    commands: Vec<(u16, u16), RECENT_COMMANDS>,
    commands_at: u64,
    /// Board pin levels as last reported (bit = pin number), kept while unconfigured too,
    /// so a new table starts from the switches' real positions.
    pins: u64,
    /// The last frame counter accepted per management sender.
    replay: ReplayGuard<MANAGEMENT_SENDERS>,
    /// When an unsecured broadcast `Identify` may be answered again.
    next_open_identify: u64,
    /// Challenges sent and not answered yet: (sender, nonce).
    challenges: Pending<MANAGEMENT_SENDERS>,
    /// When the next challenge may be sent.
    next_challenge: u64,
    /// The latched alarms.
    alarms: Alarms,
    /// The engine state was written since the alarms last looked (they look at the rest,
    /// the links, every time): set wherever `state` is written.
    state_changed: bool,
    /// What the alarms read of the running table's engine state (found when it was
    /// installed).
    watch: crate::alarms::Watch,
}

/// What the running engine is given (one [`NodeCore::run`] for all of them).
#[derive(Debug, Clone, Copy)]
enum Stimulus {
    Start,
    Home,
    Boot,
    Reset,
    Timer(u8),
    Fail(u8),
    Input { index: u8, level: bool },
    Remote { peer: u8, topic: u8 },
}

/// Why a payload is not a message the node acts on.
enum Unacted {
    /// Not a message.
    Malformed,
    /// A message meant for the tool (an answer or report of a node): received, nothing
    /// to do.
    ForTheTool,
}

/// Why a management frame is not acted on.
enum Refused {
    /// Refused (counted by its reason, and as dropped).
    Dropped,
    /// Authentic, part of the freshness handshake (a challenge sent, or answered).
    Handshake,
}

/// The engine's effects, applied to the node's timers, links and pins.
struct NodeEffects<'a, I: Io> {
    now: u64,
    table: &'a Table,
    timers: &'a mut [Option<u64>; MAX_TIMERS],
    senders: &'a mut Senders,
    radio: &'a mut Radio,
    io: &'a mut I,
}

/// The node's link senders (by peer index), with the links in alarm as counted at the
/// last look: any access that can change a sender (`DerefMut`) has them counted again;
/// [`Senders::with`] keeps the count of the one sender it changes.
#[derive(Default)]
struct Senders {
    list: Vec<link::Sender, MAX_PEERS>,
    /// Bit i: `list[i]` is in alarm, as of the last [`Senders::alarms`] (valid unless
    /// `touched`).
    alarms: u8,
    /// The list was borrowed mutably since `alarms` was counted.
    touched: bool,
}

impl core::ops::Deref for Senders {
    type Target = Vec<link::Sender, MAX_PEERS>;
    fn deref(&self) -> &Self::Target {
        &self.list
    }
}

impl core::ops::DerefMut for Senders {
    fn deref_mut(&mut self) -> &mut Self::Target {
        self.touched = true;
        &mut self.list
    }
}

impl Senders {
    /// Bit i: the link to peer i is in alarm; counted again only after a mutable borrow.
    #[inline(always)]
    fn alarms(&mut self) -> u8 {
        if self.touched {
            self.touched = false;
            self.alarms = links_in(&self.list, LinkState::Alarm);
        }
        self.alarms
    }

    /// `f` on the sender to peer `peer` (if there is one): the cached alarm bit of that one
    /// sender is then set from its state, the others are not touched (so the look after it
    /// need not count them again).
    #[inline(always)]
    fn with<R>(&mut self, peer: usize, f: impl FnOnce(&mut link::Sender) -> R) -> Option<R> {
        let sender = self.list.get_mut(peer)?;
        let r = f(sender);
        let bit = 1u8 << peer;
        if sender.state() == LinkState::Alarm {
            self.alarms |= bit;
        } else {
            self.alarms &= !bit;
        }
        Some(r)
    }
}

/// Bit i: `senders[i]` is in `state`.
fn links_in(senders: &[link::Sender], state: LinkState) -> u8 {
    senders
        .iter()
        .enumerate()
        .filter(|(_, s)| s.state() == state)
        .fold(0, |m, (i, _)| m | (1 << i))
}

/// What sending a message needs, owned by the node (one pointer to pass).
struct Radio {
    addr: u16,
    mac_seq: u8,
    counters: Counters,
    /// The management key: with it, every frame on the config PAN is secured both ways.
    key: Option<ManagementKey>,
    /// The link keys of the running table (and the previous one's, for the overlap), the
    /// peers' replay floors and handshakes: frames on the robot's PAN are secured with
    /// them, if any.
    links: PeerSecurity,
    security: SecurityCounters,
}

/// [`Radio::send_numbered`]'s frame buffer: an MPDU, or the secured headers and the
/// largest payload.
const SEND_BUFFER: usize = if MAX_MPDU > sealed::A_LEN + mac::MAX_PAYLOAD {
    MAX_MPDU
} else {
    sealed::A_LEN + mac::MAX_PAYLOAD
};

impl Radio {
    fn send(&mut self, io: &mut impl Io, pan_id: u16, dst: u16, msg: &Message<'_>) {
        match (LinkMessage::of(msg), self.securing(pan_id)) {
            (Some(m), (None, false)) => self.send_link(io, pan_id, dst, m),
            _ => self.send_numbered(io, pan_id, dst, msg, None),
        }
    }

    /// What secures a frame on `pan_id`: the management key on the config PAN (if the
    /// node has one), and whether the link keys do on the robot's PAN. Neither: in clear.
    #[inline(always)]
    fn securing(&self, pan_id: u16) -> (Option<&ManagementKey>, bool) {
        let links = pan_id != CONFIG_PAN && self.links.secured();
        let key = gated(&self.key).filter(|_| crate::FRAME_SECURITY && pan_id == CONFIG_PAN);
        (key, links)
    }

    /// [`Radio::send_numbered`] of an `Event` or `EventAck` in clear (see
    /// [`Radio::securing`]: neither key): the same frame, put together in a buffer its
    /// size, its MAC header [`mac::data_header`] of [`Radio::header`] (no security, no
    /// acknowledgement request: [`mac::PLAIN_DATA_FC`]).
    #[inline(always)]
    fn send_link(&mut self, io: &mut impl Io, pan_id: u16, dst: u16, m: LinkMessage) {
        let header = mac::data_header(&self.header(pan_id, dst));
        let mut mpdu = [0u8; mac::DATA_HEADER_LEN + LinkMessage::MAX_LEN];
        let (head, at) = mpdu.split_at_mut(mac::DATA_HEADER_LEN);
        let (Ok(head), Ok(at)) = (
            <&mut [u8; mac::DATA_HEADER_LEN]>::try_from(head),
            <&mut [u8; LinkMessage::MAX_LEN]>::try_from(at),
        ) else {
            return;
        };
        *head = header;
        let n = m.write(at);
        self.transmit(io, mpdu.get(..mac::DATA_HEADER_LEN + n));
    }

    /// Counts and transmits `frame`, if one was put together.
    #[inline(always)]
    fn transmit(&mut self, io: &mut impl Io, frame: Option<&[u8]>) {
        if let Some(frame) = frame {
            crate::count(&mut self.counters.sent);
            io.transmit_mpdu(frame);
        }
    }

    /// [`Radio::send`]; a secured frame takes `counter` if given (already drawn from the
    /// board), else the board's next.
    fn send_numbered(
        &mut self,
        io: &mut impl Io,
        pan_id: u16,
        dst: u16,
        msg: &Message<'_>,
        counter: Option<u32>,
    ) {
        let (key, links) = self.securing(pan_id);
        // The key that secures the frame and its key index: the management key on the
        // config PAN, the send key for `dst` under link keys (`Some(None)`: `dst` is not a
        // peer), none (`None`): unsecured. One secured branch, one `secure` call.
        let secured = match key {
            Some(key) => Some(Some((*key.expose(), MANAGEMENT_KEY_INDEX))),
            None if links => Some(self.links.send_key(dst)),
            None => None,
        };
        // Room for the largest payload after the secured headers, as the general codec
        // takes it (one that does not fit a frame is refused once the frame's sequence
        // number and counter are taken, as there).
        let mut mpdu = [0u8; SEND_BUFFER];
        let emitted = match secured {
            Some(send) => {
                // The message straight into the frame after its MAC and aux headers,
                // secured there ([`security::link::seal_in_place`]: the frame
                // `security::secure_default_mpdu_with` writes).
                let at = mpdu
                    .get_mut(sealed::A_LEN..sealed::A_LEN + mac::MAX_PAYLOAD)
                    .unwrap_or_default();
                let Ok(n) = msg.emit(at) else {
                    return;
                };
                let header = self.header(pan_id, dst);
                let Some(counter) = counter.or_else(|| io.next_frame_counter()) else {
                    crate::count(&mut self.security.no_counter);
                    return;
                };
                // No key for `dst` (not a peer): nothing is sent in clear instead.
                send.and_then(|(key, index)| {
                    sealed::seal_in_place::<NodeCipher>(&header, index, counter, &key, &mut mpdu, n)
                        .ok()
                })
            }
            None => {
                // The message straight into the frame after its MAC header.
                let at = mpdu
                    .get_mut(mac::DATA_HEADER_LEN..MAX_MPDU)
                    .unwrap_or_default();
                let Ok(n) = msg.emit(at) else {
                    return;
                };
                let header = self.header(pan_id, dst);
                mac::finish_data_mpdu(&header, &mut mpdu, n).ok()
            }
        };
        self.transmit(io, emitted.and_then(|len| mpdu.get(..len)));
    }

    /// The MAC header of the next frame to `dst` on `pan_id`: it takes the next sequence
    /// number.
    fn header(&mut self, pan_id: u16, dst: u16) -> Header {
        let header = Header {
            seq: self.mac_seq,
            pan_id,
            dst,
            src: self.addr,
            ack_request: false,
            secured: false,
        };
        self.mac_seq = self.mac_seq.wrapping_add(1);
        header
    }
}

impl<I: Io> Effects for NodeEffects<'_, I> {
    fn output(&mut self, output: u8, value: bool) {
        if let Some(o) = self.table.outputs.get(usize::from(output)) {
            self.io.set_pin(o.pin, value);
        }
    }
    // Out of line: inlined into the interpreter's cascade (`ecc::Run::raise`), every
    // field it reads (the links, the radio, the I/O, the clock) was loaded ahead of each
    // stimulus and kept across the cascade's loop, whether the stimulus published or not.
    #[inline(never)]
    fn publish(&mut self, p: &Publication) {
        let (pan, table) = (self.table.header.pan_id, self.table);
        for i in 0..self.senders.len() {
            if p.subscribers & (1 << i) == 0 {
                continue;
            }
            let Some(&dst) = table.peers.get(i) else {
                continue;
            };
            let (radio, io, now) = (&mut self.radio, &mut *self.io, self.now);
            let send = |m: Message<'static>| radio.send(io, pan, dst, &m);
            // A broken link refuses the event: the subscriber stalls rather than skips.
            let _ = self.senders.with(i, |s| s.push(p.topic, now, send));
        }
    }
    fn start_timer(&mut self, timer: u8, ms: u32) {
        if let Some(t) = self.timers.get_mut(usize::from(timer)) {
            *t = Some(self.now + u64::from(ms));
        }
    }
    fn cancel_timer(&mut self, timer: u8) {
        if let Some(t) = self.timers.get_mut(usize::from(timer)) {
            *t = None;
        }
    }
}

impl NodeCore {
    /// A node at `addr` on a board with pins `board_pins` (bit n: the board has pin n),
    /// booting with `table` (the newest valid slot) or none, staging pushed tables in RAM
    /// ([`NodeCore::staging_in`]). The table's identity is that of its blob, encoded here
    /// (a board boots from the blob itself: [`NodeCore::staging_in`]).
    pub fn new(
        addr: u16,
        board_pins: u64,
        table: Option<Table>,
        epochs: impl Into<Epochs>,
    ) -> Self {
        let boot = table.map(|table| Deployment {
            id: TableId::of(&table).unwrap_or(TableId::NONE),
            table,
            keys: None,
        });
        NodeCore::staging_in(addr, board_pins, boot, epochs, RamStaging::new())
    }
}

impl<S: StagingArea> NodeCore<S> {
    /// A node at `addr` on a board with pins `board_pins` (bit n: the board has pin n),
    /// booting with `boot` (the newest valid slot: its table, link keys and identity) or
    /// none; a table naming a pin the board lacks is not run (the node boots
    /// unconfigured). `epochs` start where this boot's link epochs do, newer than every
    /// epoch of the previous boots (peers only accept newer ones): a `u16` reserves none,
    /// [`Epochs::counted`] those of a persisted boot counter ([`crate::epoch`]).
    pub fn staging_in(
        addr: u16,
        board_pins: u64,
        boot: Option<Deployment>,
        epochs: impl Into<Epochs>,
        staging: S,
    ) -> Self {
        let mut node = NodeCore {
            radio: Radio {
                addr,
                mac_seq: 0,
                counters: Counters::default(),
                key: None,
                links: PeerSecurity::default(),
                security: SecurityCounters::default(),
            },
            board_pins,
            table: None,
            table_id: TableId::NONE,
            index: None,
            state: None,
            timers: [None; MAX_TIMERS],
            senders: Senders::default(),
            receivers: Vec::new(),
            ota: ota::Receiver::staging_in(board_pins, staging),
            staging: None,
            switch: SwitchOver::default(),
            epochs: epochs.into(),
            restarted: 0,
            cycles: 0,
            cycle_open: false,
            boot_pending: false,
            greetings: restart::Greetings::default(),
            booted: false,
            restarts: restart::Heard::default(),
            next_announce: 0,
            commands: Vec::new(),
            commands_at: 0,
            pins: 0,
            replay: ReplayGuard::new(),
            next_open_identify: 0,
            challenges: Pending::default(),
            next_challenge: 0,
            alarms: Alarms::default(),
            state_changed: true,
            watch: Default::default(),
        };
        if let Some(d) = boot.filter(|d| d.table.missing_pin(board_pins).is_none()) {
            node.install(d, false);
            node.boot_pending = true;
            node.booted = true;
        }
        node
    }

    /// The node (built from a table: [`NodeCore::new`]) with the link keys its running
    /// table came with: its events are secured with them. Keys that do not name exactly
    /// the running table's peers, for its generation, are not taken (the events stay
    /// refused). A board boots table and keys together from its flash slot
    /// ([`NodeCore::staging_in`]).
    pub fn with_link_keys(mut self, keys: LinkKeys) -> Self {
        if let Some(t) = &self.table {
            if keys.check(t).is_ok() {
                self.radio.links.install(Some(keys), &t.peers);
            }
        }
        self
    }

    /// Whether the running table's events are secured (it came with link keys).
    pub fn links_secured(&self) -> bool {
        self.radio.links.secured()
    }

    /// The node with its management key (provisioned): from now on it accepts on the
    /// config PAN only frames secured at ENC-MIC-64 with it, replay-checked, and secures
    /// every frame it sends there (the board's [`Io::next_frame_counter`] numbers them).
    pub fn with_management_key(mut self, key: ManagementKey) -> Self {
        self.radio.key = Some(key);
        self
    }

    /// Whether the node has a management key.
    pub fn keyed(&self) -> bool {
        self.key().is_some()
    }

    /// The management key, if the node has one and the image has frame security.
    fn key(&self) -> Option<&ManagementKey> {
        gated(&self.radio.key)
    }

    /// What the node counted of frame security.
    pub fn security_counters(&self) -> SecurityCounters {
        self.radio.security
    }

    /// The board's pins (bit n: pin n).
    pub fn board_pins(&self) -> u64 {
        self.board_pins
    }

    /// The board's input pin levels at boot (bit = pin number), read before any edge is
    /// fed: the table loaded from flash starts from the switches' real positions, without
    /// raising events for switches that were already closed.
    pub fn seed_pins(&mut self, pins: u64) {
        self.pins = pins;
        if let (Some(table), Some(index), Some(state)) = (&self.table, &self.index, &mut self.state)
        {
            let mut engine = Engine::resume_indexed(table, index, state);
            for (i, input) in table.inputs.iter().enumerate() {
                engine.sense(i as u8, level(pins, input.pin));
            }
            *state = engine.snapshot();
            self.state_changed = true;
        }
    }

    /// Drives every output of the running table to its start level (call once at boot).
    /// A held output starts low: the pin came out of reset off, there is nothing to hold.
    pub fn boot(&mut self, io: &mut impl Io) {
        if let Some(t) = &self.table {
            io.running(t.generation);
            for o in &t.outputs {
                io.set_pin(o.pin, o.start.level().unwrap_or(false));
            }
        }
    }

    /// Bit i: the level the running table drives on the pin of `next`'s output i (low
    /// where it drives none): what a held output of `next` keeps.
    fn driven_levels(&self, next: &Table) -> u16 {
        let (Some(table), Some(state)) = (&self.table, &self.state) else {
            return 0;
        };
        let high = |pin: u8| {
            (table.outputs.iter().take(16))
                .position(|o| o.pin == pin)
                .is_some_and(|j| state.outputs & (1 << j) != 0)
        };
        (next.outputs.iter().take(16))
            .enumerate()
            .fold(0, |acc, (i, o)| acc | (u16::from(high(o.pin)) << i))
    }

    /// Activation's pins, before `next` replaces the running table: the running table's
    /// outputs go to their start levels, except those `next` holds; a pin `next` does not
    /// drive goes low (nobody drives it after: a node released from its role leaves no
    /// valve energised); then `next`'s outputs go to their start levels, a held one to the
    /// level it has.
    fn drive_start(&self, next: &Table, io: &mut impl Io) {
        let holds =
            |pin: u8| (next.outputs.iter()).any(|o| o.pin == pin && o.start.level().is_none());
        let drives = |pin: u8| next.outputs.iter().any(|o| o.pin == pin);
        if let Some(old) = &self.table {
            for o in old.outputs.iter().filter(|o| !holds(o.pin)) {
                let level = o.start.level().filter(|_| drives(o.pin));
                io.set_pin(o.pin, level.unwrap_or(false));
            }
        }
        let before = self.driven_levels(next);
        for (i, o) in next.outputs.iter().enumerate() {
            let now = i < 16 && before & (1 << i) != 0;
            io.set_pin(o.pin, o.start.level().unwrap_or(now));
        }
    }

    /// Runs `table` from now on: its charts start in their initial states, or in their
    /// idle states when `at_idle` (it replaces a table that rested at its idle point).
    fn install(&mut self, deployed: Deployment, at_idle: bool) {
        let Deployment { table, keys, id } = deployed;
        self.radio.links.install(keys, &table.peers);
        // The table's index is built once, here, and kept beside it.
        let index = Index::new(&table);
        let mut engine = Engine::new_indexed(&table, &index, self.driven_levels(&table));
        if at_idle {
            engine.rest();
        }
        for (i, input) in table.inputs.iter().enumerate() {
            engine.sense(i as u8, level(self.pins, input.pin));
        }
        self.state = Some(engine.snapshot());
        self.state_changed = true;
        self.timers = [None; MAX_TIMERS];
        let epoch = self.epochs.take();
        self.senders.clear();
        self.restarted = 0;
        self.cycle_open = false;
        self.boot_pending = false;
        self.greetings = restart::Greetings::default();
        self.booted = false;
        self.restarts.forget();
        self.alarms.new_table();
        for _ in &table.peers {
            let _ = self.senders.push(link::Sender::new(epoch));
        }
        // Links from peers that stay keep their place in the publisher's numbering; the
        // receivers follow the table's peers by index (`receivers[i]` hears `peers[i]`).
        let old = core::mem::take(&mut self.receivers);
        for &p in &table.peers {
            let kept = old.iter().find(|(a, _)| *a == p).map(|&(_, r)| r);
            let _ = self.receivers.push((p, kept.unwrap_or_default()));
        }
        self.index = Some(index);
        self.watch = crate::alarms::Watch::of(&table);
        self.table = Some(table);
        self.table_id = id;
    }

    pub fn addr(&self) -> u16 {
        self.radio.addr
    }

    /// The running table, if configured.
    pub fn table(&self) -> Option<&Table> {
        self.table.as_ref()
    }

    pub fn generation(&self) -> u32 {
        self.table.as_ref().map_or(0, |t| t.generation)
    }

    pub fn engine_state(&self) -> Option<&EngineState> {
        self.state.as_ref()
    }

    pub fn counters(&self) -> Counters {
        self.radio.counters
    }

    fn links_in(&self, state: LinkState) -> u8 {
        links_in(&self.senders, state)
    }

    /// Bit i: the link to peer i is in alarm (the peer stopped acknowledging).
    pub fn link_alarms(&self) -> u8 {
        self.links_in(LinkState::Alarm)
    }

    /// Bit i: the link to peer i is broken (its queue overflowed).
    pub fn links_broken(&self) -> u8 {
        self.links_in(LinkState::Broken)
    }

    /// The epoch of the newest link numbering.
    pub fn epoch(&self) -> u16 {
        self.epochs.current()
    }

    /// The link epochs: the newest, and how far the boot counter reserves them.
    pub fn epochs(&self) -> Epochs {
        self.epochs
    }

    /// The operator's reset of the links: every link that is not idle and healthy (broken,
    /// in alarm, or with events not yet acknowledged) starts over in a new epoch, which its
    /// subscriber accepts from seq 0; what it had queued is dropped (it belongs to before
    /// the reset). Idle healthy links keep their numbering, so a reset of a quiet machine
    /// takes no epoch. Returns (and keeps for status) the links re-established.
    fn restart_links(&mut self) -> u8 {
        let stuck = |s: &link::Sender| s.state() != LinkState::Ok || s.unacked() > 0;
        let restart = self
            .senders
            .iter()
            .enumerate()
            .filter(|(_, s)| stuck(s))
            .fold(0u8, |m, (i, _)| m | (1 << i));
        if restart != 0 {
            let epoch = self.epochs.take();
            for (i, s) in self.senders.iter_mut().enumerate() {
                if restart & (1 << i) != 0 {
                    *s = link::Sender::new(epoch);
                }
            }
        }
        self.restarted = restart;
        restart
    }

    /// What the node needs of its flash now, if anything.
    pub fn flash_request(&self) -> Option<FlashRequest<'_>> {
        if let Some(s) = &self.staging {
            return Some(FlashRequest::Stage(self.ota.blob(s.len)));
        }
        if self.switch.confirming().is_some() {
            return Some(FlashRequest::Confirm);
        }
        if let Some((_, target)) = self.switch.activating() {
            return Some(match target {
                switch::Target::Staged { trial } => FlashRequest::Activate { trial },
                switch::Target::Previous => FlashRequest::Rollback,
            });
        }
        self.epochs.wants_count().then_some(FlashRequest::CountBoot)
    }

    /// The board counted a boot for [`FlashRequest::CountBoot`]: `boots` is the count it
    /// persisted (`None`: it failed; asked again once another epoch is taken). Returns
    /// whether the node wants another count at once (the epochs taken need more).
    pub fn boot_counted(&mut self, boots: Option<u32>) -> bool {
        self.epochs.counted_boot(boots);
        self.epochs.wants_count()
    }

    /// The node booted with `generation` confirmed in its other slot: what a rollback
    /// returns to.
    pub fn with_previous(mut self, generation: u32) -> Self {
        self.switch.set_previous(generation);
        self
    }

    /// The board confirmed the running table (`ok`) or failed to: answer the tool.
    pub fn confirmed(&mut self, ok: bool, io: &mut impl Io) {
        let generation = self.generation();
        if let Some(from) = self.switch.confirmed(ok) {
            let reply = if ok {
                ConfigReply::Confirmed
            } else {
                ConfigReply::Refused(Refusal::Flash)
            };
            self.send(
                io,
                CONFIG_PAN,
                from,
                &Message::ConfigReply { generation, reply },
            );
        }
    }

    /// The node booted with `generation` staged in flash (the tool may finish the
    /// switch-over).
    pub fn with_staged(mut self, generation: u32) -> Self {
        self.switch.set_staged(generation);
        self
    }

    /// The generation staged for the switch-over (0: none).
    pub fn staged_generation(&self) -> u32 {
        self.switch.staged()
    }

    /// Whether the node is idle: configured, not faulted, every chart in its idle state
    /// or another of its resting states (`Chart::rests`), no timer running, no event of
    /// its own unacknowledged (unconfigured: idle).
    pub fn idle(&self) -> bool {
        self.resting(|c, cur| c.rests_in(cur))
    }

    /// Whether the node is at rest: as [`NodeCore::idle`], but a chart may also be in its
    /// initial state (not homed: nothing moves there either). A switch-over waits for this;
    /// the table it activates starts homed only if the node was idle.
    pub fn at_rest(&self) -> bool {
        self.resting(|c, cur| c.rests_in(cur) || cur == c.initial)
    }

    fn resting(&self, chart_rests: impl Fn(&config_schema::Chart, u8) -> bool) -> bool {
        let (Some(t), Some(st)) = (&self.table, &self.state) else {
            return true;
        };
        st.fault.is_none()
            && t.charts
                .iter()
                .zip(st.current.iter())
                .all(|(c, &cur)| chart_rests(c, cur))
            && self.timers.iter().all(Option::is_none)
            && self.senders.iter().all(|s| s.unacked() == 0)
    }

    /// The earliest time [`NodeCore::poll`] has work.
    pub fn deadline(&self) -> u64 {
        let mut at = u64::MAX;
        let links = self.senders.iter().map(|s| s.deadline());
        let announce = self.table.is_none().then_some(self.next_announce);
        let others = [
            announce,
            self.radio.links.greeting(),
            self.greetings.deadline(),
            self.switch.deadline(),
        ];
        for t in self.timers.iter().copied().chain(links).chain(others) {
            at = at.min(t.unwrap_or(u64::MAX));
        }
        at
    }

    /// Raises the table's START event: a START at the idle point that sets the node going
    /// begins a cycle.
    fn run_start(&mut self, now: u64, io: &mut impl Io) {
        self.run_starting(now, io, Stimulus::Start);
    }

    /// [`NodeCore::run`] of a START (the command or the button): one at the idle point
    /// that sets the node going opens a cycle (`Status::cycles`).
    fn run_starting(&mut self, now: u64, io: &mut impl Io, stimulus: Stimulus) {
        let was_idle = self.idle();
        self.run(now, io, stimulus);
        self.cycle_open |= was_idle && !self.idle();
    }

    /// Counts a cycle under way that is over: the node is back at its idle point.
    fn note_idle(&mut self) {
        if self.cycle_open && self.idle() {
            self.cycle_open = false;
            self.cycles = self.cycles.wrapping_add(1);
        }
    }

    /// Runs the engine on the running table with effects applied to this node: one
    /// function for every stimulus.
    fn run(&mut self, now: u64, io: &mut impl Io, stimulus: Stimulus) {
        self.on_engine(now, io, |engine, fx| match stimulus {
            Stimulus::Start => {
                engine.start(fx);
            }
            Stimulus::Home => {
                engine.home(fx);
            }
            Stimulus::Boot => {
                engine.boot(fx);
            }
            Stimulus::Reset => engine.reset(fx),
            Stimulus::Timer(timer) => engine.timer_expired(timer, fx),
            Stimulus::Fail(code) => engine.fail(code, fx),
            Stimulus::Input { index, level } => engine.input(index, level, fx),
            Stimulus::Remote { peer, topic } => {
                engine.remote(peer, topic, fx);
            }
        });
    }

    /// `f` with the engine on the running table's state in place and the effects applied
    /// to this node (nothing without a table); then whether the alarms may read
    /// something else is noted.
    #[inline(always)]
    fn on_engine<I: Io>(
        &mut self,
        now: u64,
        io: &mut I,
        f: impl FnOnce(&mut Engine<'_, &mut EngineState, &Index>, &mut NodeEffects<'_, I>),
    ) {
        let (Some(table), Some(index), Some(state)) = (&self.table, &self.index, &mut self.state)
        else {
            return;
        };
        // What the alarms read of the state, as it was: the engine runs on it in place.
        let watch = self.watch;
        let before = crate::alarms::Reads::of(watch, state);
        let mut fx = NodeEffects {
            now,
            table,
            timers: &mut self.timers,
            senders: &mut self.senders,
            radio: &mut self.radio,
            io,
        };
        f(&mut Engine::on(table, index, state), &mut fx);
        self.state_changed |= before.changed(watch, state);
    }

    fn send(&mut self, io: &mut impl Io, pan: u16, dst: u16, msg: &Message<'_>) {
        self.radio.send(io, pan, dst, msg);
    }

    /// [`NodeCore::send`]; a secured frame takes `counter` if given.
    fn send_numbered(
        &mut self,
        io: &mut impl Io,
        pan: u16,
        dst: u16,
        msg: &Message<'_>,
        counter: Option<u32>,
    ) {
        self.radio.send_numbered(io, pan, dst, msg, counter);
    }

    /// The level of board pin `pin` is `level` (repeating an unchanged level is harmless:
    /// events come from edges).
    pub fn input(&mut self, pin: u8, level: bool, now: u64, io: &mut impl Io) {
        // A pin past the bitmap is on no board (and in no validated table).
        let bit = 1u64.checked_shl(u32::from(pin)).unwrap_or(0);
        if level {
            self.pins |= bit;
        } else {
            self.pins &= !bit;
        }
        let index = self
            .table
            .as_ref()
            .and_then(|t| t.inputs.iter().position(|i| i.pin == pin));
        let Some(index) = index else {
            return;
        };
        if self.senses(index, level) {
            // Not an edge: the engine raises nothing, its mirror variable holds the level
            // already and the alarms see what they saw (the plant repeats levels).
            return;
        }
        let is_start = self.table.as_ref().is_some_and(|t| {
            level && t.start.is_some() && t.inputs.get(index).and_then(|i| i.rise) == t.start
        });
        let restarts = self.table.as_ref().is_some_and(|t| {
            level && (is_start || (index < 16 && t.safety.restart & (1 << index) != 0))
        });
        if restarts && self.alarms.blocking().is_some() {
            // A fault alarm is latched: the press is refused (the level is kept).
            if let (Some(table), Some(ix), Some(state)) =
                (&self.table, &self.index, &mut self.state)
            {
                Engine::on(table, ix, state).sense(index as u8, level);
                self.state_changed = true;
            }
            return;
        }
        let stimulus = Stimulus::Input {
            index: index as u8,
            level,
        };
        if is_start {
            self.run_starting(now, io, stimulus);
        } else {
            self.run(now, io, stimulus);
        }
        self.look(now, io);
        self.note_idle();
    }

    /// The running engine senses table input `index` at `level` already, and its mirror
    /// variable (if any) holds it.
    fn senses(&self, index: usize, level: bool) -> bool {
        let (Some(table), Some(state)) = (&self.table, &self.state) else {
            return false;
        };
        let bit = 1u16 << (index & 15);
        let var = table.inputs.get(index).and_then(|i| i.var);
        let mirrored = var.is_none_or(|v| {
            (state.vars.get(usize::from(v))).is_some_and(|&x| x == i32::from(level))
        });
        (state.inputs & bit != 0) == level && mirrored
    }

    /// After a stimulus: a link alarm faults the node under `on_link_alarm: Fault`; then
    /// the alarms look at the node.
    #[inline]
    fn look(&mut self, now: u64, io: &mut impl Io) {
        let link_alarms = self.senders.alarms();
        // Links in alarm asked first: the table is read only then.
        if link_alarms != 0 && self.table.as_ref().is_some_and(|t| t.safety.link_fault) {
            self.fail_link(now, io);
        }
        // The common look (nothing changed: `state_changed` is clear, nothing to take) asked
        // first, before its `Seen` is put together.
        if self.alarms.quiet(link_alarms, self.state_changed) {
            return;
        }
        if let (Some(table), Some(state)) = (&self.table, &self.state) {
            let changed = core::mem::take(&mut self.state_changed);
            let seen = Seen {
                table,
                state,
                link_alarms,
            };
            self.alarms.look(seen, now, changed);
        }
    }

    /// A link alarm faults the node (`on_link_alarm: Fault`): out of [`NodeCore::look`],
    /// which runs after every stimulus.
    #[inline(never)]
    fn fail_link(&mut self, now: u64, io: &mut impl Io) {
        let code = config_schema::alarm::FAULT_LINK;
        self.run(now, io, Stimulus::Fail(code));
    }

    /// The latched alarms.
    pub fn alarms(&self) -> &Alarms {
        &self.alarms
    }

    /// The alarms as reported to command `ack` at `now`.
    pub fn alarm_report(&self, ack: u16, now: u64) -> config_schema::alarm::AlarmReport {
        let seen = self.seen();
        self.alarms.report(ack, seen, now)
    }

    fn seen(&self) -> Option<Seen<'_>> {
        let (table, state) = (self.table.as_ref()?, self.state.as_ref()?);
        Some(Seen {
            table,
            state,
            link_alarms: self.link_alarms(),
        })
    }

    /// Expired timers, link retransmissions, announcements.
    pub fn poll(&mut self, now: u64, io: &mut impl Io) {
        self.poll_due(now, io);
        self.look(now, io);
        self.note_idle();
    }

    fn poll_due(&mut self, now: u64, io: &mut impl Io) {
        if core::mem::take(&mut self.boot_pending) {
            // Peers learn that this node's actuators may stand anywhere.
            self.run(now, io, Stimulus::Boot);
            // And that its charts started over (a secured node's handshake greets them).
            if !self.radio.links.secured() {
                self.greetings.boot(now);
            }
        }
        if self.greetings.due(now) {
            self.greet(now, io);
        }
        for timer in 0..MAX_TIMERS {
            if self.timers[timer].is_some_and(|t| t <= now) {
                self.timers[timer] = None;
                self.run(now, io, Stimulus::Timer(timer as u8));
            }
        }
        if self.switch.poll(now) {
            self.run_start(now, io);
        }
        while let Some(peer) = self.radio.links.next_greeting(now) {
            if let Some(pan) = self.table.as_ref().map(|t| t.header.pan_id) {
                let flags = if self.booted { restart::GREETING } else { 0 };
                self.challenge_on(pan, peer, flags, now, io);
            }
        }
        if let Some(table) = &self.table {
            let pan = table.header.pan_id;
            let radio = &mut self.radio;
            for (sender, &dst) in self.senders.iter_mut().zip(table.peers.iter()) {
                let before = sender.counters().retried;
                sender.poll(now, |m| radio.send(io, pan, dst, &m));
                radio.counters.retried += sender.counters().retried - before;
            }
        } else if now >= self.next_announce {
            self.next_announce = now + ANNOUNCE_MS;
            let announce = self.announce(0);
            self.send(io, CONFIG_PAN, BROADCAST, &announce);
        }
    }

    /// `nonce`: that of the `Identify` it answers (0: unprompted).
    fn announce(&self, nonce: u64) -> Message<'static> {
        let mut role = heapless::String::new();
        if let Some(t) = &self.table {
            role = t.header.role.clone();
        }
        Message::Announce(Announce {
            firmware: FIRMWARE_VERSION,
            generation: self.generation(),
            role,
            table: self.table_id,
            staged: self.switch.staged(),
            nonce,
        })
    }

    /// The node's status, answering command `ack`, with the board runtime's counters.
    pub fn status(&self, ack: u16, runtime: RuntimeCounters) -> Status {
        let mut s = Status {
            ack,
            role: heapless::String::new(),
            generation: self.generation(),
            table: self.table_id,
            staged: self.switch.staged(),
            previous: self.switch.previous(),
            trial: self.switch.trial(),
            states: Vec::new(),
            outputs: 0,
            inputs: 0,
            fault: None,
            link_alarms: self.link_alarms(),
            links_broken: self.links_broken(),
            links_restarted: self.restarted,
            epoch: self.epochs.current(),
            counters: self.radio.counters,
            runtime,
            cycles: self.cycles,
        };
        if let (Some(t), Some(st)) = (&self.table, &self.state) {
            s.role = t.header.role.clone();
            for c in 0..t.charts.len() {
                let _ = s.states.push(st.current[c]);
            }
            s.outputs = st.outputs;
            s.inputs = st.inputs;
            s.fault = st.fault.map(fault_code);
        }
        s
    }

    /// A PSDU arrived (FCS included): a harness on a medium that carries the FCS. The FCS
    /// is checked and cut off here, a bad one dropped and counted as the radio edge does
    /// ([`NodeCore::dropped_at_edge`]), and the MPDU goes to [`NodeCore::receive_mpdu`].
    pub fn receive(&mut self, psdu: &[u8], now: u64, io: &mut impl Io) {
        match mac::strip_fcs(psdu) {
            Ok(mpdu) => self.receive_mpdu(mpdu, now, io),
            Err(_) => self.dropped_at_edge(),
        }
    }

    /// An MPDU arrived (the frame without its FCS, checked at the radio edge: the board's
    /// radio in hardware, the host medium transport or the QEMU UART in software).
    pub fn receive_mpdu(&mut self, mpdu: &[u8], now: u64, io: &mut impl Io) {
        if !self.link_in_clear(mpdu, now, io) && !self.link_secured(mpdu, now, io) {
            self.receive_frame(mpdu, now, io);
        }
        self.look(now, io);
        self.note_idle();
    }

    /// The radio edge dropped a frame (its FCS did not match, or it was not a PSDU):
    /// counted with the frames the core drops. Nothing else changes (no stimulus: the
    /// alarms have nothing new to look at).
    pub fn dropped_at_edge(&mut self) {
        crate::count(&mut self.radio.counters.dropped);
    }

    /// The short path of an unsecured `Event` or `EventAck` to this node on the running
    /// table's PAN, in the frame this firmware writes ([`mac::PLAIN_DATA_FC`]: no security,
    /// no acknowledgement request): the MAC header checked as three compares against what
    /// the node expects, the message read in place and handled at once (an event of a
    /// link's first 16,384 read in this code, [`LinkMessage::event_fields`], and taken by
    /// [`NodeCore::event_in_clear`]; any other event or ack read by a call). `false`: not
    /// such a frame, nothing done; [`NodeCore::receive_frame`] takes it (and does for these
    /// frames exactly what this does: counted as received, [`NodeCore::on_link`]).
    #[inline(always)]
    fn link_in_clear(&mut self, mpdu: &[u8], now: u64, io: &mut impl Io) -> bool {
        let Some((head, payload)) = mpdu.split_first_chunk::<{ mac::DATA_HEADER_LEN }>() else {
            return false;
        };
        let Some(table) = &self.table else {
            return false;
        };
        let pan = table.header.pan_id;
        let [f0, f1, _, p0, p1, d0, d1, ref src @ ..] = *head;
        if u16::from_le_bytes([f0, f1]) != mac::PLAIN_DATA_FC
            || u16::from_le_bytes([p0, p1]) != pan
            || u16::from_le_bytes([d0, d1]) != self.radio.addr
            || pan == CONFIG_PAN
            || self.radio.links.secured()
        {
            return false;
        }
        let src = u16::from_le_bytes(*src);
        if let Some(event) = LinkMessage::event_fields(payload) {
            crate::count(&mut self.radio.counters.received);
            // `on_link`'s event arm; this path's ack goes in clear.
            self.event_in_clear(pan, src, event, now, io);
            return true;
        }
        // Any other event (an epoch or seq past the short read) or an ack: `on_link`, as
        // the general path.
        let Some(m) = LinkMessage::parse_fields(payload) else {
            return false;
        };
        crate::count(&mut self.radio.counters.received);
        self.on_link(m, src, now, io);
        true
    }

    /// The short path of a secured `Event` or `EventAck` from a peer to this node on the
    /// running table's PAN under link keys, in the frame this firmware writes
    /// ([`security::link`]): the headers compared as bytes, the peer's receive key looked
    /// up, the payload opened in a buffer its size and read in place, then the replay
    /// check and the handshake ([`PeerSecurity::admit`]) and [`NodeCore::on_link`].
    /// One that opens to another message (a challenge, an answer) goes on as the general
    /// path's does ([`NodeCore::receive_opened`]). `false`: not such a frame, or its key
    /// is not found, nothing done; [`NodeCore::receive_frame`] takes it, and does
    /// for these frames exactly what this does.
    #[inline(never)]
    fn link_secured(&mut self, mpdu: &[u8], now: u64, io: &mut impl Io) -> bool {
        let Some(table) = &self.table else {
            return false;
        };
        let pan = table.header.pan_id;
        if pan == CONFIG_PAN || !self.radio.links.secured() {
            return false;
        }
        let Some(frame) = SealedLink::new(mpdu, pan, self.radio.addr) else {
            return false;
        };
        let src = frame.src();
        let links = &mut self.radio.links;
        let Some(key) = links.receive_key(src, frame.key_index(), self.radio.addr, now) else {
            return false;
        };
        let mut plain = [0u8; LinkMessage::MAX_LEN];
        let payload = match frame.open::<NodeCipher>(&key, &mut plain) {
            Ok(payload) => payload,
            Err(e) => {
                let staged = self.switch.staged();
                links.refused(Some(frame.key_index()), staged, e, &mut self.radio.security);
                crate::count(&mut self.radio.counters.dropped);
                return true;
            }
        };
        let opened = Opened {
            header: frame.header(),
            aux: frame.aux(),
            payload,
        };
        let Some(m) = LinkMessage::parse(payload) else {
            // Another message (a challenge, an answer): the general path's, opened once.
            self.receive_opened(&opened.header, Some(&opened), payload, false, now, io);
            return true;
        };
        let parsed = Ok::<_, Unacted>(Message::from(m));
        match links.admit(&opened, &parsed, now, &mut self.radio.security) {
            Verdict::Accept(_) => {}
            verdict => {
                self.not_accepted(verdict, pan, now, io);
                return true;
            }
        }
        crate::count(&mut self.radio.counters.received);
        self.on_link(m, src, now, io);
        true
    }

    /// A peer's frame that opened on `pan` and is not to be acted on (any [`Verdict`] but
    /// `Accept`): counted, answered or challenged back as the verdict says.
    fn not_accepted(&mut self, verdict: Verdict<'_>, pan: u16, now: u64, io: &mut impl Io) {
        match verdict {
            Verdict::Accept(_) | Verdict::Answered => {}
            Verdict::Dropped => crate::count(&mut self.radio.counters.dropped),
            Verdict::Challenge { peer, challenge } => {
                if challenge {
                    self.challenge_peer(peer, now, io);
                }
            }
            Verdict::Answer {
                peer,
                nonce,
                answer,
                challenge,
                renumber,
            } => {
                // It knows no counter of ours: it booted (or is new to this table),
                // and may have no receiving side of our link to it either.
                if renumber {
                    self.renumber_link(peer, None, now);
                }
                if answer {
                    self.send(io, pan, peer, &Message::ChallengeAnswer { nonce });
                }
                if challenge {
                    self.challenge_peer(peer, now, io);
                }
                if nonce & restart::GREETING != 0 {
                    self.peer_restarted(peer, now, io);
                }
            }
        }
    }

    #[inline(never)]
    fn receive_frame(&mut self, mpdu: &[u8], now: u64, io: &mut impl Io) {
        let (header, payload) = match Frame::parse_mpdu(mpdu) {
            Ok(Frame::Data { header, payload }) => (header, payload),
            _ => {
                crate::count(&mut self.radio.counters.dropped);
                return;
            }
        };
        let pan_ok = header.pan_id == CONFIG_PAN
            || self
                .table
                .as_ref()
                .is_none_or(|t| t.header.pan_id == header.pan_id);
        if (header.dst != self.radio.addr && header.dst != BROADCAST) || !pan_ok {
            crate::count(&mut self.radio.counters.dropped);
            return;
        }
        // The opened payload's buffer, zeroed only for a secured frame.
        let mut scratch: [u8; mac::MAX_PAYLOAD];
        let management = header.pan_id == CONFIG_PAN && self.key().is_some();
        if management && header.secured && header.dst == BROADCAST {
            // No one key secures a broadcast to every node: these are other nodes'
            // announcements (secured with their own keys), which a node never reads.
            return;
        }
        let peers = header.pan_id != CONFIG_PAN && self.radio.links.secured();
        if peers && !header.secured {
            crate::count(&mut self.radio.security.not_secured);
            crate::count(&mut self.radio.counters.dropped);
            return;
        }
        // One open and one parse for both secured paths (and the unsecured one).
        let opened = if (management || peers) && header.secured {
            scratch = [0u8; mac::MAX_PAYLOAD];
            let opened = security::open_default_mpdu_with::<NodeCipher, _>(
                mpdu,
                |header, aux| self.lookup(header, aux, now),
                &mut scratch,
            );
            match opened {
                Ok(opened) => Some(opened),
                Err(e) => {
                    if management {
                        peer_security::count_refusal(e, &mut self.radio.security);
                    } else {
                        let staged = self.switch.staged();
                        let index = peer_security::aux_key_index(payload);
                        self.radio
                            .links
                            .refused(index, staged, e, &mut self.radio.security);
                    }
                    crate::count(&mut self.radio.counters.dropped);
                    return;
                }
            }
        } else if header.secured {
            // Secured, and no key for it: a table without link keys counts it; an
            // unconfigured node (a machine's traffic it is not part of yet), or one with
            // that generation staged (a peer that switched a moment earlier), does not.
            let ahead = self.switch.staged() != 0 && header.pan_id != CONFIG_PAN;
            if self.table.is_some() && !ahead {
                crate::count(&mut self.radio.security.unknown_key);
            }
            crate::count(&mut self.radio.counters.dropped);
            return;
        } else {
            // In clear (an event or an acknowledgement in the frame this firmware writes
            // took `link_in_clear` before).
            None
        };
        self.receive_opened(&header, opened.as_ref(), payload, management, now, io);
    }

    /// A frame to this node past the MAC checks (`header`; `payload` its payload) and,
    /// secured, opened (`opened`; `management`: on the config PAN under the management
    /// key, else from a peer): its message parsed, the replay floor and the handshake
    /// checked, and the message acted on. Out of line: the secured short path hands it a
    /// peer's frame it opened that holds another message (a challenge, an answer), which
    /// is not opened a second time.
    #[inline(never)]
    fn receive_opened(
        &mut self,
        header: &Header,
        opened: Option<&Opened<'_>>,
        payload: &[u8],
        management: bool,
        now: u64,
        io: &mut impl Io,
    ) {
        let parsed = match Message::parse_node(opened.map_or(payload, |o| o.payload)) {
            Ok(Some(msg)) => Ok(msg),
            Ok(None) => Err(Unacted::ForTheTool),
            Err(_) => Err(Unacted::Malformed),
        };
        let authentic = match opened {
            None => false,
            Some(opened) if management => match self.admit_management(opened, &parsed, now, io) {
                Ok(()) => true,
                Err(Refused::Dropped) => {
                    crate::count(&mut self.radio.counters.dropped);
                    return;
                }
                Err(Refused::Handshake) => return,
            },
            Some(opened) => {
                match self
                    .radio
                    .links
                    .admit(opened, &parsed, now, &mut self.radio.security)
                {
                    Verdict::Accept(_) => true,
                    verdict => {
                        self.not_accepted(verdict, header.pan_id, now, io);
                        return;
                    }
                }
            }
        };
        let msg = match parsed {
            Ok(msg) => msg,
            // Replies, statuses and announcements are for the tool.
            Err(Unacted::ForTheTool) => {
                crate::count(&mut self.radio.counters.received);
                return;
            }
            Err(Unacted::Malformed) => {
                crate::count(&mut self.radio.counters.dropped);
                return;
            }
        };
        let is_management = matches!(
            msg,
            Message::ConfigBegin { .. }
                | Message::ConfigChunk { .. }
                | Message::ConfigEnd { .. }
                | Message::Command { .. }
                | Message::Switch { .. }
        );
        if self.key().is_some() && is_management && !authentic {
            // A scan cannot be secured with every node's key: an unsecured broadcast
            // Identify is answered (secured), rate-limited; nothing else is taken.
            let scan = header.dst == BROADCAST
                && header.pan_id == CONFIG_PAN
                && matches!(
                    msg,
                    Message::Command {
                        command: Command::Identify { .. },
                        ..
                    }
                );
            if !scan {
                crate::count(&mut self.radio.security.not_secured);
                crate::count(&mut self.radio.counters.dropped);
                return;
            }
            if now < self.next_open_identify {
                // A scan asked again within the second: not a security refusal.
                crate::count(&mut self.radio.counters.dropped);
                return;
            }
            self.next_open_identify = now + OPEN_IDENTIFY_MS;
        }
        let link = LinkMessage::of(&msg);
        if link.is_some() && header.pan_id == CONFIG_PAN {
            // Events and their acks are the robot's, on its PAN (secured there under link
            // keys): on the config PAN they are no peer's, whoever they claim to be from.
            if self.radio.links.secured() {
                crate::count(&mut self.radio.security.not_secured);
            }
            crate::count(&mut self.radio.counters.dropped);
            return;
        }
        crate::count(&mut self.radio.counters.received);
        let src = header.src;
        let reply_pan = header.pan_id;
        if let Some(m) = link {
            self.on_link(m, src, now, io);
            return;
        }
        match msg {
            Message::ConfigBegin { .. }
            | Message::ConfigChunk { .. }
            | Message::ConfigEnd { .. } => self.on_config(&msg, src, reply_pan, io),
            // A peer that booted, on a robot without link keys (a secured robot's challenge
            // is its handshake's, taken before this): it asks for our link to it numbered
            // again in the epoch its nonce names ([`NodeCore::ask_renumbering`]).
            Message::Challenge { nonce }
                if opened.is_none() && reply_pan != CONFIG_PAN && !self.radio.links.secured() =>
            {
                match (self.peer(src), u16::try_from(nonce)) {
                    (Some(_), Ok(wanted)) => self.renumber_link(src, Some(wanted), now),
                    (Some(_), Err(_)) if nonce == restart::GREETING => {
                        self.peer_restarted(src, now, io)
                    }
                    _ => crate::count(&mut self.radio.counters.dropped),
                }
            }
            Message::Command { id, command } => {
                self.on_command(id, command, src, reply_pan, now, io)
            }
            Message::Switch { generation, step } => {
                self.on_switch(generation, step, src, reply_pan, now, io)
            }
            // Parsed as `Unacted::ForTheTool`.
            _ => {}
        }
    }

    /// The key and the sender's extended address that open a secured frame with `header`
    /// and `aux` at `now`: on the config PAN the management key (key index 0; our own
    /// frames reflected back are not the tool's), on the robot's PAN the peer's link key.
    fn lookup(&self, header: &Header, aux: &AuxRepr, now: u64) -> Option<([u8; 16], [u8; 8])> {
        if header.pan_id != CONFIG_PAN {
            return self.radio.links.lookup(header, aux, self.radio.addr, now);
        }
        let key = gated(&self.radio.key)?;
        (aux.key_id.index() == Some(MANAGEMENT_KEY_INDEX) && header.src != self.radio.addr)
            .then(|| (*key.expose(), ext_addr(header.pan_id, header.src)))
    }

    /// Checks the counter of a management frame that opened (ENC-MIC-64, key index 0, the
    /// sender's extended address from its short address) against the last one accepted
    /// from that sender; `message` is its payload parsed. Every refusal is counted by its
    /// reason.
    ///
    /// A sender whose counter the node does not know (none since boot) is challenged
    /// instead: its frame is not acted on; the node answers `Challenge { nonce }`, the nonce
    /// being that frame's own counter (never used before), and takes the counter of the
    /// sender's `ChallengeAnswer` with that nonce as its floor, if it comes within
    /// [`peer_security::ANSWER_WITHIN_MS`] of the challenge. A frame captured before the
    /// answer has a lower counter: no replay passes a reboot.
    fn admit_management<E>(
        &mut self,
        opened: &Opened<'_>,
        message: &Result<Message<'_>, E>,
        now: u64,
        io: &mut impl Io,
    ) -> Result<(), Refused> {
        let src = opened.header.src;
        let counter = opened.aux.frame_counter;
        let c = &mut self.radio.security;
        if self.replay.last(src, MANAGEMENT_KEY_INDEX).is_none() {
            if self.challenges.answered(src, message, now) {
                peer_security::accept(&mut self.replay, src, MANAGEMENT_KEY_INDEX, counter, c);
                return Err(Refused::Handshake);
            }
            crate::count(&mut c.challenged);
            if now >= self.next_challenge {
                self.next_challenge = now + CHALLENGE_MS;
                self.challenge(src, now, io);
            }
            return Err(Refused::Handshake);
        }
        if peer_security::accept(&mut self.replay, src, MANAGEMENT_KEY_INDEX, counter, c) {
            Ok(())
        } else {
            Err(Refused::Dropped)
        }
    }

    /// Sends `src` a challenge on the config PAN (see [`NodeCore::challenge_on`]).
    fn challenge(&mut self, src: u16, now: u64, io: &mut impl Io) {
        self.challenge_on(CONFIG_PAN, src, 0, now, io);
    }

    /// Sends `dst` on `pan` a challenge whose nonce is the counter of the challenge frame
    /// itself (with `flags`: [`restart::GREETING`] for a booted node's greeting; the nonce
    /// [`restart::RESET_GREETING`] alone, remembered nowhere, for a reset's; to a peer,
    /// the nonce of a challenge it has not answered yet, if any:
    /// [`crate::peer_security::PeerSecurity::challenge`]), and remembers it: on the config PAN
    /// for the management path, on the robot's for the peers' (one sender for both).
    fn challenge_on(&mut self, pan: u16, dst: u16, flags: u32, now: u64, io: &mut impl Io) {
        let Some(counter) = io.next_frame_counter() else {
            crate::count(&mut self.radio.security.no_counter);
            return;
        };
        let nonce = if flags == restart::RESET_GREETING {
            // Nothing to answer for: the floors stay (no challenge is pending).
            flags
        } else if pan == CONFIG_PAN {
            self.challenges.sent(dst, counter | flags, now);
            counter | flags
        } else {
            self.radio.links.challenge(dst, counter, flags, now)
        };
        self.send_numbered(io, pan, dst, &Message::Challenge { nonce }, Some(counter));
    }

    /// Our link to `peer` starts again from seq 0 in a new epoch (the peer rebooted: its
    /// receiver waits for seq 0), with the events it has not acknowledged: this node's
    /// next epoch, or `wanted` if the peer asked for a newer one (a link that numbers in
    /// `wanted` or a newer one already is left as it is: the ask came late, or twice).
    /// Unasked (`None`: a secured peer's challenge, whose answer lets the peer take our
    /// events: they are sent again at once), only a link some of whose events were
    /// acknowledged in its epoch: one still at seq 0 is taken by a fresh receiver as it
    /// is, and the challenge may have been sent before the peer took its first events
    /// (their acknowledgement lost): numbered again, they would be delivered twice. A
    /// challenge sent after the peer acknowledged one of them (it booted since) is newer
    /// than that acknowledgement's counter; one sent before it is a replay by then.
    fn renumber_link(&mut self, peer: u16, wanted: Option<u16>, now: u64) {
        let Some(i) = self.peer(peer) else { return };
        let Some(sender) = self.senders.get_mut(i) else {
            return;
        };
        match wanted {
            Some(w) if !sender.older_than(w) => return,
            None if sender.starts_at_zero() => return sender.resend(now),
            _ => {}
        }
        let epoch = match wanted {
            Some(w) => self.epochs.take_at_least(w),
            None => self.epochs.take(),
        };
        sender.renumber(epoch, now);
    }

    /// Challenges peer `peer` on the robot's PAN (see [`crate::peer_security`]).
    fn challenge_peer(&mut self, peer: u16, now: u64, io: &mut impl Io) {
        let Some(pan) = self.table.as_ref().map(|t| t.header.pan_id) else {
            return;
        };
        self.challenge_on(pan, peer, 0, now, io);
    }

    /// A node without link keys that booted, or any node reset under way, greets each of
    /// its peers ([`restart`]): in clear, or secured with the nonce
    /// [`restart::RESET_GREETING`] (a secured node's boot greets with its handshake).
    #[cold]
    #[inline(never)]
    fn greet(&mut self, now: u64, io: &mut impl Io) {
        let Some(pan) = self.table.as_ref().map(|t| t.header.pan_id) else {
            return;
        };
        let secured = self.radio.links.secured();
        let greeting = Message::Challenge {
            nonce: restart::GREETING,
        };
        // By index: sending borrows the node (and a copy of the peers costs flash).
        let mut i = 0;
        while let Some(&peer) = self.table.as_ref().and_then(|t| t.peers.get(i)) {
            if secured {
                self.challenge_on(pan, peer, restart::RESET_GREETING, now, io);
            } else {
                self.radio.send(io, pan, peer, &greeting);
            }
            i += 1;
        }
    }

    /// Peer `peer` greeted this node: it booted, its charts started over. A node under
    /// way ([`NodeCore::under_way`]) waits for events that peer's charts will not send:
    /// it faults (`FAULT_PEER_RESTART`, its outputs at their fault levels) rather than
    /// stall, at the first copy of the greeting it hears; a node at rest carries on.
    #[cold]
    #[inline(never)]
    fn peer_restarted(&mut self, peer: u16, now: u64, io: &mut impl Io) {
        let Some(i) = self.peer(peer) else { return };
        if self.restarts.first(i, now) && self.under_way() {
            let code = config_schema::alarm::FAULT_PEER_RESTART;
            self.run(now, io, Stimulus::Fail(code));
        }
    }

    /// Whether the node is under way: it runs a table, is not faulted, and a chart of it
    /// is neither in its idle nor in its initial state (a cycle or homing under way).
    pub fn under_way(&self) -> bool {
        let (Some(t), Some(st)) = (&self.table, &self.state) else {
            return false;
        };
        st.fault.is_none() && restart::under_way(t, &st.current)
    }

    fn peer(&self, addr: u16) -> Option<usize> {
        self.table.as_ref()?.peers.iter().position(|&p| p == addr)
    }

    /// An event or an acknowledgement from `src`.
    fn on_link(&mut self, m: LinkMessage, src: u16, now: u64, io: &mut impl Io) {
        match m {
            LinkMessage::Event { epoch, seq, topic } => {
                self.on_event(src, epoch, seq, topic, now, io)
            }
            LinkMessage::EventAck { epoch, next } => {
                let Some(peer) = self.peer(src) else { return };
                let Some(table) = &self.table else { return };
                let pan = table.header.pan_id;
                let radio = &mut self.radio;
                let send = |m: Message<'static>| radio.send(io, pan, src, &m);
                self.senders
                    .with(peer, |s| s.on_ack(epoch, next, now, send));
            }
        }
    }

    fn on_event(&mut self, src: u16, epoch: u16, seq: u16, topic: u8, now: u64, io: &mut impl Io) {
        let mut deliver = Vec::new();
        let Some((peer, ack)) = self.receive_event(src, (epoch, seq, topic), &mut deliver) else {
            return;
        };
        let pan = self.table.as_ref().map_or(CONFIG_PAN, |t| t.header.pan_id);
        match ack {
            Some(next) => self.send(io, pan, src, &Message::EventAck { epoch, next }),
            None => self.ask_renumbering(peer, pan, src, epoch, now, io),
        }
        for &topic in deliver.iter() {
            crate::count(&mut self.radio.counters.delivered);
            let peer = peer as u8;
            self.run(now, io, Stimulus::Remote { peer, topic });
        }
    }

    /// The short path of [`NodeCore::receive_event`]: event `seq` of `epoch` from `src` is
    /// the one its link receiver expects next, and it holds none (a running link's every
    /// event: [`link::Receiver::next_in_order`]). The peer's index and the ack's `next`;
    /// the one topic to deliver is the event's. `None`: any other event, nothing changed.
    #[inline(always)]
    fn next_in_order(&mut self, src: u16, epoch: u16, seq: u16) -> Option<(usize, u16)> {
        let peer = self.peer(src)?;
        let (_, receiver) = self.receivers.get_mut(peer)?;
        Some((peer, receiver.next_in_order(epoch, seq)?))
    }

    /// Event `seq` (`topic`, `epoch`) from `src` to its link receiver, which pushes the
    /// topics to deliver now onto `deliver` (empty), in order: the peer's index and the
    /// ack's `next` if one is due. `None`: `src` is no peer (the frame counted as
    /// dropped) or has no receiver.
    #[inline(always)]
    fn receive_event(
        &mut self,
        src: u16,
        (epoch, seq, topic): (u16, u16, u8),
        deliver: &mut Vec<u8, { link::WINDOW + 1 }>,
    ) -> Option<(usize, Option<u16>)> {
        let Some(peer) = self.peer(src) else {
            crate::count(&mut self.radio.counters.dropped);
            return None;
        };
        let (_, receiver) = self.receivers.get_mut(peer)?;
        Some((peer, receiver.receive(epoch, seq, topic, deliver)))
    }

    /// [`NodeCore::on_event`] of an event that came in clear on the running table's PAN
    /// `pan` with no link keys (so its ack goes in clear: [`Radio::send_link`]), written
    /// out for [`NodeCore::link_in_clear`] for the event its link expects next while none
    /// is held (a running link's every event: [`NodeCore::next_in_order`]): the same steps,
    /// the engine run without the stimulus' dispatch ([`NodeCore::run_remote`]). Any other
    /// event goes to `on_event` itself.
    #[inline(always)]
    fn event_in_clear(
        &mut self,
        pan: u16,
        src: u16,
        (epoch, seq, topic): (u16, u16, u8),
        now: u64,
        io: &mut impl Io,
    ) {
        let Some((peer, next)) = self.next_in_order(src, epoch, seq) else {
            self.on_event(src, epoch, seq, topic, now, io);
            return;
        };
        let ack = LinkMessage::EventAck { epoch, next };
        self.radio.send_link(io, pan, src, ack);
        crate::count(&mut self.radio.counters.delivered);
        self.run_remote(now, io, peer as u8, topic);
    }

    /// The receiver of peer `peer` (address `src`) dropped its event of `epoch`: on a
    /// robot without link keys, a fresh receiver (this node booted while the peer numbered
    /// on) asks the peer, with a `Challenge` in clear whose nonce is the epoch it asks for,
    /// to number its link again from seq 0 ([`link::Receiver::ask`]; the peer:
    /// [`NodeCore::renumber_link`]). A secured robot's links are numbered again by its
    /// handshake ([`crate::peer_security`]).
    #[cold]
    #[inline(never)]
    fn ask_renumbering(
        &mut self,
        peer: usize,
        pan: u16,
        src: u16,
        epoch: u16,
        now: u64,
        io: &mut impl Io,
    ) {
        if pan == CONFIG_PAN || self.radio.links.secured() {
            return;
        }
        let Some((_, receiver)) = self.receivers.get_mut(peer) else {
            return;
        };
        if let Some(wanted) = receiver.ask(epoch, now) {
            let nonce = u32::from(wanted);
            self.send(io, pan, src, &Message::Challenge { nonce });
        }
    }

    /// [`NodeCore::run`] of a remote event: `topic` from peer `peer` (written out for the
    /// event path, without the stimulus' dispatch). The subscribed event is found here and
    /// raised as [`Engine::remote`] raises it ([`Engine::event`]); none: the engine is not
    /// run (it would raise nothing, and change nothing the alarms read).
    #[inline(always)]
    fn run_remote(&mut self, now: u64, io: &mut impl Io, peer: u8, topic: u8) {
        let Some(event) = (self.table.as_ref()).and_then(|t| t.subscribed(peer, topic)) else {
            return;
        };
        self.on_engine(now, io, |engine, fx| engine.event(event, fx));
    }

    fn on_config(&mut self, msg: &Message<'_>, src: u16, pan: u16, io: &mut impl Io) {
        // Nothing touches the staging buffer while its table is being persisted; the
        // answer comes once it runs (the runtime persists before it reads another frame).
        if self.staging.is_some() || self.switch.activating().is_some() {
            return;
        }
        let generation = self.generation();
        // On trial a transfer would be staged over the previous table, the only confirmed
        // one: a new one is refused, and so is one begun before the trial (its transfer
        // forgotten), or a power cut before `confirm` would boot no table at all.
        let transfer = match *msg {
            Message::ConfigBegin { generation, .. } => Some(generation),
            Message::ConfigChunk { generation, .. } | Message::ConfigEnd { generation }
                if self.ota.receiving() == Some(generation) =>
            {
                Some(generation)
            }
            _ => None,
        };
        if let (true, Some(g)) = (self.switch.trial(), transfer) {
            self.ota.abort();
            let reply = ConfigReply::Refused(Refusal::OnTrial);
            self.send(
                io,
                pan,
                src,
                &Message::ConfigReply {
                    generation: g,
                    reply,
                },
            );
            return;
        }
        match self.ota.on_message(msg, generation, self.switch.staged()) {
            Some(Outcome::Reply(reply)) => {
                let gen = match *msg {
                    Message::ConfigBegin { generation, .. }
                    | Message::ConfigChunk { generation, .. }
                    | Message::ConfigEnd { generation } => generation,
                    _ => 0,
                };
                self.send(
                    io,
                    pan,
                    src,
                    &Message::ConfigReply {
                        generation: gen,
                        reply,
                    },
                );
            }
            Some(Outcome::Stage { generation, len }) => {
                // The old table keeps running; the new one waits for the switch-over.
                self.staging = Some(Staging {
                    generation,
                    len,
                    from: src,
                });
            }
            None => {}
        }
    }

    /// The board staged the transfer (`ok`) or failed to: answer the tool.
    pub fn staged(&mut self, ok: bool, io: &mut impl Io) {
        let Some(staging) = self.staging.take() else {
            return;
        };
        let generation = staging.generation;
        self.ota.persisted(ok);
        let reply = if ok {
            self.switch.set_staged(generation);
            ConfigReply::Staged
        } else {
            // Its erase may have gone over the previous table: no rollback to it.
            self.switch.set_previous(0);
            ConfigReply::Refused(Refusal::Flash)
        };
        self.send(
            io,
            CONFIG_PAN,
            staging.from,
            &Message::ConfigReply { generation, reply },
        );
    }

    /// The board activated the staged slot and read back its table and keys (`None`: the
    /// flash failed, or the slot no longer decodes): switch to it atomically (outputs to
    /// their start levels, held ones kept, new engine), answer the tool, and run a START
    /// held during the switch-over.
    pub fn activated(&mut self, deployed: Option<Deployment>, now: u64, io: &mut impl Io) {
        let rollback = matches!(
            self.switch.activating(),
            Some((_, switch::Target::Previous))
        );
        let generation = if rollback {
            self.switch.previous()
        } else {
            self.switch.staged()
        };
        let deployed = deployed.filter(|d| d.table.generation == generation);
        let running = self.generation();
        let (from, start) = self.switch.activated(deployed.is_some(), running);
        let reply = match deployed {
            Some(deployed) => {
                // A machine that rested at its idle point stays homed; one stopped
                // anywhere else (or a node that was never configured) needs homing.
                let at_idle = self.table.is_some() && self.idle();
                io.running(deployed.table.generation);
                self.drive_start(&deployed.table, io);
                self.install(deployed, at_idle);
                ConfigReply::Activated
            }
            None => {
                // The staged table's slot is revoked (its serial may be written): a push
                // of it again stages it again.
                if !rollback {
                    self.switch.set_staged(0);
                    self.ota.unstaged();
                }
                ConfigReply::Refused(Refusal::Flash)
            }
        };
        if let Some(from) = from {
            self.send(
                io,
                CONFIG_PAN,
                from,
                &Message::ConfigReply { generation, reply },
            );
        }
        if start {
            self.run_start(now, io);
        }
    }

    /// A `Switch` step from the tool.
    fn on_switch(
        &mut self,
        generation: u32,
        step: SwitchStep,
        src: u16,
        pan: u16,
        now: u64,
        io: &mut impl Io,
    ) {
        let idle = self.at_rest();
        let running = self.generation();
        let reply = match self.switch.step(generation, step, src, running, idle, now) {
            switch::Action::Reply(r) => r,
            // Answered once the board has switched.
            switch::Action::Activate(_) | switch::Action::Confirm => return,
            switch::Action::Disarmed { start } => {
                if start {
                    self.run_start(now, io);
                }
                ConfigReply::Disarmed
            }
        };
        self.send(io, pan, src, &Message::ConfigReply { generation, reply });
    }

    fn on_command(
        &mut self,
        id: u16,
        cmd: Command,
        src: u16,
        pan: u16,
        now: u64,
        io: &mut impl Io,
    ) {
        if let Command::Identify { nonce } = cmd {
            let a = self.announce(nonce);
            self.send(io, pan, src, &a);
            return;
        }
        // Only a command that does something is remembered: a status asked again is
        // answered again, and the tools' polls do not push a START out of the memory.
        let acts = matches!(
            cmd,
            Command::Start | Command::Reset | Command::Home | Command::Ack
        );
        if acts {
            // After a quiet time the ids remembered are another time's: forgotten.
            // In ms since boot, whole: `now as u32` wrapped after 49.7 days, and a command
            // that came 2^32 ms after the last was taken for a repeat of it.
            if now.saturating_sub(self.commands_at) >= u64::from(REPEAT_MS) {
                self.commands.clear();
            }
            self.commands_at = now;
        }
        let repeat = acts && self.commands.contains(&(src, id));
        if !repeat {
            if acts {
                if self.commands.is_full() {
                    crate::remove_at(&mut self.commands, 0);
                }
                let _ = self.commands.push((src, id));
            }
            // A latched fault alarm: nothing starts or moves until it is acknowledged.
            let blocked = self.alarms.blocking().is_some();
            match cmd {
                Command::Start | Command::Home if blocked => {}
                // Armed for a switch-over: the START waits for it.
                Command::Start if self.switch.hold_start() => {}
                Command::Start => self.run_start(now, io),
                // Homing moves actuators: not while armed for a switch-over.
                Command::Home if self.switch.armed() => {}
                Command::Home => self.run(now, io, Stimulus::Home),
                Command::Reset => {
                    // Its charts start over: under way, peers may wait for events they
                    // will now never send, so it greets them as a boot does.
                    let under_way = self.under_way();
                    // Links first: what the reset publishes goes out in the new epoch.
                    self.restart_links();
                    self.run(now, io, Stimulus::Reset);
                    if under_way {
                        self.greetings.boot(now);
                    }
                }
                Command::Ack => {
                    // Alarms raised by what happened so far are latched before the ack.
                    self.look(now, io);
                    let link_alarms = self.link_alarms();
                    if let (Some(table), Some(state)) = (&self.table, &self.state) {
                        let seen = Seen {
                            table,
                            state,
                            link_alarms,
                        };
                        self.alarms.ack(seen);
                    }
                }
                Command::Identify { .. }
                | Command::Status
                | Command::Security
                | Command::Alarms => {}
            }
        }
        if matches!(cmd, Command::Alarms | Command::Ack) {
            let report = Message::Alarms(self.alarm_report(id, now));
            self.send(io, pan, src, &report);
            return;
        }
        if cmd == Command::Security {
            let report = Message::Security(SecurityReport {
                ack: id,
                keyed: self.key().is_some(),
                counters: self.radio.security,
            });
            self.send(io, pan, src, &report);
            return;
        }
        let status = Message::Status(self.status(id, io.runtime_counters()));
        self.send(io, pan, src, &status);
    }
}

/// The bytes of [`NodeCore`] and of its larger parts, as this build lays them out, with
/// the transfer staged outside it as on a board (the RAM breakdown of docs/boards.md:
/// `cargo test -p node-fw --features std --test host_runtime runtime_future_size --
/// --nocapture`).
pub fn footprint() -> [(&'static str, usize); 13] {
    use core::mem::size_of;
    type Board = &'static mut RamStaging;
    [
        ("NodeCore<RamStaging>", size_of::<NodeCore>()),
        ("NodeCore (staging outside)", size_of::<NodeCore<Board>>()),
        ("  Option<Table>", size_of::<Option<Table>>()),
        ("  Option<Index>", size_of::<Option<Index>>()),
        ("  Option<EngineState>", size_of::<Option<EngineState>>()),
        ("  ota::Receiver", size_of::<ota::Receiver<Board>>()),
        ("  senders", size_of::<Vec<link::Sender, MAX_PEERS>>()),
        (
            "  receivers",
            size_of::<Vec<(u16, link::Receiver), MAX_PEERS>>(),
        ),
        ("  PeerSecurity", size_of::<PeerSecurity>()),
        ("  Alarms", size_of::<Alarms>()),
        ("  SwitchOver", size_of::<SwitchOver>()),
        (
            "  ReplayGuard + Pending",
            size_of::<ReplayGuard<MANAGEMENT_SENDERS>>() + size_of::<Pending<MANAGEMENT_SENDERS>>(),
        ),
        (
            "  Option<ManagementKey>",
            size_of::<Option<ManagementKey>>(),
        ),
    ]
}

/// Whether pin `pin` is high in `pins` (bit = pin number; pins past 63 never are).
fn level(pins: u64, pin: u8) -> bool {
    pins.checked_shr(u32::from(pin)).is_some_and(|p| p & 1 != 0)
}

/// The one-byte fault code of status: 1..=4 for the interpreter's bounds, 0x80 | code for
/// a `Fault` action.
pub fn fault_code(f: Fault) -> u8 {
    match f {
        Fault::ChainLimit { .. } => 1,
        Fault::QueueFull { .. } => 2,
        Fault::Cascade { .. } => 3,
        Fault::Expr { .. } => 4,
        Fault::Action { code, .. } => 0x80 | code,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use config_schema::{Action, Output, Subscription};
    use proptest::prelude::*;

    const PAN: u16 = 0x4242;
    const A: u16 = 1;
    const B: u16 = 2;
    const C: u16 = 3;

    /// B: a button published to peer A (topic 3), a lamp toggled by A's topic 3; peers A
    /// and C.
    fn table_b(link_fault: bool) -> Table {
        let mut t = Table::empty("B");
        t.header.pan_id = PAN;
        t.safety.link_fault = link_fault;
        let press = test_tables::button(&mut t, 5);
        t.peers.push(A).unwrap();
        t.peers.push(C).unwrap();
        t.publications
            .push(Publication {
                event: press,
                topic: 3,
                subscribers: 0b01,
            })
            .unwrap();
        let remote = t.push_event().unwrap();
        t.outputs.push(Output::safe(7, false)).unwrap();
        t.subscriptions
            .push(Subscription {
                publisher: 0,
                topic: 3,
                event: remote,
            })
            .unwrap();
        test_tables::toggle(&mut t, remote, &[Action::Drive { mask: 1, value: 1 }]);
        t
    }

    #[derive(Default, Debug, PartialEq)]
    struct Board {
        out: std::vec::Vec<std::vec::Vec<u8>>,
        pins: std::vec::Vec<(u8, bool)>,
    }

    impl Io for Board {
        fn transmit(&mut self, psdu: &[u8]) {
            self.out.push(psdu.to_vec());
        }
        fn set_pin(&mut self, pin: u8, level: bool) {
            self.pins.push((pin, level));
        }
    }

    #[derive(Debug, Clone)]
    enum Op {
        Frame(std::vec::Vec<u8>),
        Press(bool),
        Poll(u64),
        /// A's events of `epoch` from seq 0 to `count`, in order: the link past the
        /// one-byte seqs, so that random events later are in order with a 2-byte seq.
        Burst {
            epoch: u16,
            count: u16,
        },
    }

    /// The bytes of link message `m`.
    fn link_bytes(m: LinkMessage) -> std::vec::Vec<u8> {
        let mut out = [0u8; LinkMessage::MAX_LEN];
        let n = m.write(&mut out);
        out[..n].to_vec()
    }

    /// A data MPDU: frame control `fc`, sequence number `seq`, PAN, destination and source
    /// `pan_dst_src`, then `payload`.
    fn mpdu(fc: u16, seq: u8, pan_dst_src: [u16; 3], payload: &[u8]) -> std::vec::Vec<u8> {
        let mut f = std::vec::Vec::new();
        f.extend_from_slice(&fc.to_le_bytes());
        f.push(seq);
        for v in pan_dst_src {
            f.extend_from_slice(&v.to_le_bytes());
        }
        f.extend_from_slice(payload);
        f
    }

    /// A's event `(epoch, seq, topic)` to B in clear, on B's PAN.
    fn event_frame(epoch: u16, seq: u16, topic: u8) -> std::vec::Vec<u8> {
        let event = link_bytes(LinkMessage::Event { epoch, seq, topic });
        mpdu(mac::PLAIN_DATA_FC, seq as u8, [PAN, B, A], &event)
    }

    fn frame() -> impl Strategy<Value = std::vec::Vec<u8>> {
        let fc = prop_oneof![
            6 => Just(mac::PLAIN_DATA_FC),
            1 => Just(mac::PLAIN_DATA_FC | 1 << 5),
            1 => Just(mac::PLAIN_DATA_FC & !(1 << 12)),
            1 => Just(mac::PLAIN_DATA_FC | 1 << 3),
            1 => any::<u16>(),
        ];
        let pan = prop_oneof![6 => Just(PAN), 1 => Just(0x1111u16), 1 => Just(CONFIG_PAN)];
        let dst = prop_oneof![6 => Just(B), 1 => Just(BROADCAST), 1 => Just(9u16)];
        let src = prop_oneof![6 => Just(A), 1 => Just(C), 1 => Just(9u16)];
        // Seqs on both sides of the one-byte varint too (after a burst, in order).
        let varint = prop_oneof![4 => 0u16..6, 1 => 0x7Eu16..0x86, 1 => any::<u16>()];
        // Epochs on both sides of the one-byte varint (the short read's bound).
        let epoch = prop_oneof![4 => 0u16..3, 1 => 0x7Eu16..0x82];
        let payload = prop_oneof![
            4 => (epoch.clone(), varint.clone(), prop_oneof![Just(3u8), Just(4u8)])
                .prop_map(|(epoch, seq, topic)| LinkMessage::Event { epoch, seq, topic }),
            2 => (epoch, varint).prop_map(|(epoch, next)| LinkMessage::EventAck { epoch, next }),
        ]
        .prop_map(link_bytes);
        let payload = prop_oneof![
            6 => payload,
            1 => proptest::collection::vec(any::<u8>(), 0..12),
        ];
        (fc, any::<u8>(), pan, dst, src, payload, 0usize..40).prop_map(
            |(fc, seq, pan, dst, src, payload, cut)| {
                let mut f = mpdu(fc, seq, [pan, dst, src], &payload);
                if cut < f.len() && cut % 8 == 0 {
                    f.truncate(cut);
                }
                f
            },
        )
    }

    fn op() -> impl Strategy<Value = Op> {
        prop_oneof![
            6 => frame().prop_map(Op::Frame),
            2 => any::<bool>().prop_map(Op::Press),
            1 => (0u64..3000).prop_map(Op::Poll),
            1 => (0u16..2, 120u16..136).prop_map(|(epoch, count)| Op::Burst { epoch, count }),
        ]
    }

    /// Everything of a node the short path could change.
    fn observe(n: &NodeCore) -> std::string::String {
        format!(
            "{:?} {:?} {:?} {:?} {:?} {:?} {:?} {:?} {} {} {} {:?}",
            n.radio.counters,
            n.radio.security,
            n.radio.links,
            n.radio.mac_seq,
            n.receivers,
            n.senders.list,
            n.state,
            n.timers,
            n.senders.alarms,
            n.state_changed,
            n.cycles,
            n.alarms,
        )
    }

    proptest! {
        /// The short path of an unsecured link frame ([`NodeCore::link_in_clear`]) does
        /// exactly what the general path does: the same frames out, the same pins, the same
        /// counters, links, engine state and alarms, over random frames (the short path's
        /// and every near miss), presses and polls.
        #[test]
        fn the_short_path_of_a_link_frame_is_the_general_path(
            link_fault in any::<bool>(),
            ops in proptest::collection::vec(op(), 1..60),
        ) {
            let node = || NodeCore::new(B, 1 << 5 | 1 << 7, Some(table_b(link_fault)), 1);
            let mut pair = Pair::<Board>::new(node);
            for op in ops {
                pair.apply(op)?;
            }
        }
    }

    /// The same node twice, on its own board each: one takes frames as a node does
    /// (`receive_mpdu`, its short paths first), the other on the general path only.
    struct Pair<B> {
        fast: NodeCore,
        general: NodeCore,
        bf: B,
        bg: B,
        now: u64,
    }

    impl<B: Io + Default + PartialEq + core::fmt::Debug> Pair<B> {
        fn new(node: impl Fn() -> NodeCore) -> Self {
            let mut pair = Pair {
                fast: node(),
                general: node(),
                bf: B::default(),
                bg: B::default(),
                now: 0,
            };
            pair.fast.poll(0, &mut pair.bf);
            pair.general.poll(0, &mut pair.bg);
            pair
        }

        /// `op` to both: the same frames out, pins, counters, links, engine state and
        /// alarms after it.
        fn apply(&mut self, op: Op) -> Result<(), TestCaseError> {
            let now = self.now;
            match op {
                Op::Frame(mpdu) => {
                    self.fast.receive_mpdu(&mpdu, now, &mut self.bf);
                    self.general.receive_frame(&mpdu, now, &mut self.bg);
                    self.general.look(now, &mut self.bg);
                    self.general.note_idle();
                }
                Op::Press(level) => {
                    self.fast.input(5, level, now, &mut self.bf);
                    self.general.input(5, level, now, &mut self.bg);
                }
                Op::Poll(dt) => {
                    self.now += dt;
                    self.fast.poll(self.now, &mut self.bf);
                    self.general.poll(self.now, &mut self.bg);
                }
                Op::Burst { epoch, count } => {
                    for seq in 0..count {
                        self.apply(Op::Frame(event_frame(epoch, seq, 3)))?;
                    }
                }
            }
            prop_assert_eq!(&self.bf, &self.bg);
            prop_assert_eq!(observe(&self.fast), observe(&self.general));
            Ok(())
        }
    }

    /// The link key `from` secures its frames to `to` with in generation `generation`.
    fn link_key(generation: u32, from: u16, to: u16) -> [u8; 16] {
        let mut key = [(from * 16 + to) as u8; 16];
        key[0] = generation as u8;
        key
    }

    /// B's link keys (peers A and C) for generation `generation`.
    fn keys_b(generation: u32) -> LinkKeys {
        let mut keys = LinkKeys {
            generation,
            peers: Vec::new(),
        };
        for p in [A, C] {
            let peer = config_schema::link_keys::PeerKeys {
                peer: p,
                send: link_key(generation, B, p),
                receive: link_key(generation, p, B),
            };
            keys.peers.push(peer).unwrap();
        }
        keys
    }

    /// A board with a frame counter.
    #[derive(Default, Debug, PartialEq)]
    struct Counting {
        board: Board,
        counter: u32,
    }

    impl Io for Counting {
        fn transmit(&mut self, psdu: &[u8]) {
            self.board.transmit(psdu);
        }
        fn set_pin(&mut self, pin: u8, level: bool) {
            self.board.set_pin(pin, level);
        }
        fn next_frame_counter(&mut self) -> Option<u32> {
            self.counter = self.counter.wrapping_add(1);
            Some(self.counter)
        }
    }

    /// A frame to B, secured by `src` (under its key to B unless `wrong_key`), with key
    /// index `index`, counter `counter`, its control field `fc`'s flags, then `damage`d
    /// (a byte xored) if any.
    #[derive(Debug, Clone)]
    struct Secured {
        src: u16,
        dst: u16,
        ack_request: bool,
        msg: SecuredMsg,
        /// The generation whose key (and key index, unless `index`) secures it.
        generation: u32,
        index: Option<u8>,
        counter: u32,
        wrong_key: bool,
        damage: Option<(usize, u8)>,
    }

    #[derive(Debug, Clone)]
    enum SecuredMsg {
        Link(LinkMessage),
        Challenge(u32),
        /// The answer to B's last challenge to the sender (if any).
        Answer,
        Other(std::vec::Vec<u8>),
    }

    /// The nonce of the last challenge B sent to `peer` (read from `out`) under
    /// generation `generation`'s keys.
    fn last_challenge(out: &[std::vec::Vec<u8>], peer: u16, generation: u32) -> Option<u32> {
        out.iter().rev().find_map(|psdu| {
            let mut scratch = [0u8; mac::MAX_PAYLOAD];
            let key = link_key(generation, B, peer);
            let opened = security::open_default(
                psdu,
                |h, _| (h.dst == peer).then(|| (key, ext_addr(h.pan_id, B))),
                &mut scratch,
            )
            .ok()?;
            match Message::parse(opened.payload) {
                Ok(Message::Challenge { nonce }) => Some(nonce),
                _ => None,
            }
        })
    }

    impl Secured {
        /// The frame, an answer answering B's last challenge under generation `running`.
        fn mpdu(&self, out: &[std::vec::Vec<u8>], running: u32) -> std::vec::Vec<u8> {
            let mut payload = [0u8; mac::MAX_PAYLOAD];
            let n = match &self.msg {
                SecuredMsg::Link(m) => Message::from(*m).emit(&mut payload).unwrap(),
                SecuredMsg::Challenge(nonce) => {
                    let m = Message::Challenge { nonce: *nonce };
                    m.emit(&mut payload).unwrap()
                }
                SecuredMsg::Answer => {
                    let nonce = last_challenge(out, self.src, running).unwrap_or(0);
                    let m = Message::ChallengeAnswer { nonce };
                    m.emit(&mut payload).unwrap()
                }
                SecuredMsg::Other(bytes) => {
                    payload[..bytes.len()].copy_from_slice(bytes);
                    bytes.len()
                }
            };
            let header = Header {
                seq: 0,
                pan_id: PAN,
                dst: self.dst,
                src: self.src,
                ack_request: self.ack_request,
                secured: false,
            };
            let key = if self.wrong_key {
                link_key(self.generation, self.src, C)
            } else {
                link_key(self.generation, self.src, B)
            };
            let index = self
                .index
                .unwrap_or(security::link_key_index(self.generation));
            let mut mpdu = [0u8; MAX_MPDU];
            let Ok(len) = security::secure_default_mpdu_with::<security::SoftAes>(
                &header,
                &AuxRepr::new(index, self.counter),
                &key,
                ext_addr(PAN, self.src),
                &payload[..n],
                &mut mpdu,
            ) else {
                return std::vec::Vec::new();
            };
            let mut f = mpdu[..len].to_vec();
            if let Some((at, x)) = self.damage {
                let at = at % f.len();
                f[at] ^= x;
            }
            f
        }
    }

    fn secured() -> impl Strategy<Value = Secured> {
        let src = prop_oneof![4 => Just(A), 2 => Just(C), 1 => Just(B), 1 => Just(9u16)];
        let dst = prop_oneof![8 => Just(B), 1 => Just(BROADCAST), 1 => Just(C)];
        let link = prop_oneof![
            4 => (0u16..3, prop_oneof![4 => 0u16..6, 1 => any::<u16>()], prop_oneof![Just(3u8), Just(4u8)])
                .prop_map(|(epoch, seq, topic)| LinkMessage::Event { epoch, seq, topic }),
            2 => (0u16..3, 0u16..6).prop_map(|(epoch, next)| LinkMessage::EventAck { epoch, next }),
        ];
        let msg = prop_oneof![
            8 => link.prop_map(SecuredMsg::Link),
            2 => Just(SecuredMsg::Answer),
            1 => any::<u32>().prop_map(SecuredMsg::Challenge),
            1 => proptest::collection::vec(any::<u8>(), 0..12).prop_map(SecuredMsg::Other),
        ];
        let index = prop_oneof![8 => Just(None), 1 => any::<u8>().prop_map(Some)];
        let counter = prop_oneof![8 => 1u32..200, 1 => Just(u32::MAX), 1 => any::<u32>()];
        let damage = prop_oneof![8 => Just(None), 1 => (any::<usize>(), 1u8..=255).prop_map(Some)];
        (
            (src, dst, any::<bool>(), msg),
            (0u32..3, index, counter),
            prop_oneof![9 => Just(false), 1 => Just(true)],
            damage,
        )
            .prop_map(
                |((src, dst, ack, msg), (generation, index, counter), wrong_key, damage)| Secured {
                    src,
                    dst,
                    ack_request: ack && counter % 7 == 0,
                    msg,
                    generation,
                    index,
                    counter,
                    wrong_key,
                    damage,
                },
            )
    }

    #[derive(Debug, Clone)]
    enum SecuredOp {
        Frame(Secured),
        Press(bool),
        Poll(u64),
    }

    proptest! {
        /// The short path of a secured link frame ([`NodeCore::link_secured`]) does exactly
        /// what the general path does: the same frames out (the acks, challenges and
        /// answers it sends, byte for byte), the same pins, counters, security counters,
        /// links, engine state and alarms, over random secured frames from peers and
        /// others (events, acks, challenges, answers, anything; wrong keys and key
        /// indices, replayed and exhausted counters, damaged bytes), presses and polls.
        #[test]
        fn the_short_path_of_a_secured_link_frame_is_the_general_path(
            link_fault in any::<bool>(),
            switched in any::<bool>(),
            staged in any::<bool>(),
            ops in proptest::collection::vec(
                prop_oneof![
                    8 => secured().prop_map(SecuredOp::Frame),
                    2 => any::<bool>().prop_map(SecuredOp::Press),
                    1 => (0u64..3000).prop_map(SecuredOp::Poll),
                ],
                1..60,
            ),
        ) {
            // Generation 0 running, or 1 switched to from it (0's receive keys kept for
            // the overlap); the next one staged or not.
            let running = u32::from(switched);
            let node = || {
                let mut node = NodeCore::new(B, 1 << 5 | 1 << 7, Some(table_b(link_fault)), 1)
                    .with_link_keys(keys_b(0));
                if switched {
                    let mut next = table_b(link_fault);
                    next.generation = 1;
                    let id = TableId::of(&next).unwrap();
                    node.install(
                        Deployment {
                            table: next,
                            keys: Some(keys_b(1)),
                            id,
                        },
                        false,
                    );
                }
                if staged {
                    node = node.with_staged(running + 1);
                }
                node
            };
            let mut pair = Pair::<Counting>::new(node);
            prop_assert!(pair.fast.links_secured());
            prop_assert_eq!(pair.fast.generation(), running);
            for op in ops {
                let op = match op {
                    SecuredOp::Frame(f) => Op::Frame(f.mpdu(&pair.bf.board.out, running)),
                    SecuredOp::Press(level) => Op::Press(level),
                    SecuredOp::Poll(dt) => Op::Poll(dt),
                };
                pair.apply(op)?;
            }
        }

        /// A secured message ([`Radio::send_numbered`], under link keys or the management
        /// key) is the frame the general codec writes
        /// (`security::secure_default_with`, FCS and all), with the sequence number and frame
        /// counter it takes; nothing to a node that is no peer, or past the last counter.
        #[test]
        fn a_secured_message_is_the_general_codecs_frame(
            m in prop_oneof![
                (any::<u16>(), any::<u16>(), any::<u8>())
                    .prop_map(|(epoch, seq, topic)| Message::Event { epoch, seq, topic }),
                (any::<u16>(), any::<u16>())
                    .prop_map(|(epoch, next)| Message::EventAck { epoch, next }),
                any::<u32>().prop_map(|nonce| Message::Challenge { nonce }),
                any::<u32>().prop_map(|nonce| Message::ChallengeAnswer { nonce }),
            ],
            dst in prop_oneof![Just(A), Just(C), Just(9u16)],
            counter in prop_oneof![any::<u32>(), Just(u32::MAX - 1)],
            seq in any::<u8>(),
            management in any::<bool>(),
        ) {
            const MK: [u8; 16] = [0x5C; 16];
            let t = table_b(false);
            let mut node = NodeCore::new(B, 1 << 5 | 1 << 7, Some(t), 1).with_link_keys(keys_b(0));
            if management {
                node = node.with_management_key(ManagementKey::from_bytes(MK));
            }
            // On the config PAN under the management key, else on the robot's under
            // link keys.
            let (pan, key, index) = if management {
                (CONFIG_PAN, MK, MANAGEMENT_KEY_INDEX)
            } else {
                (PAN, link_key(0, B, dst), security::link_key_index(0))
            };
            node.radio.mac_seq = seq;
            let mut board = Counting { counter, ..Counting::default() };
            node.radio.send(&mut board, pan, dst, &m);
            let sent = counter.wrapping_add(1);
            let mut payload = [0u8; mac::MAX_PAYLOAD];
            let n = m.emit(&mut payload).unwrap();
            let header = Header {
                seq,
                pan_id: pan,
                dst,
                src: B,
                ack_request: false,
                secured: false,
            };
            let mut mpdu = [0u8; MAX_PSDU];
            let general = security::secure_default_with::<security::SoftAes>(
                &header,
                &AuxRepr::new(index, sent),
                &key,
                ext_addr(pan, B),
                &payload[..n],
                &mut mpdu,
            )
            .ok()
            .filter(|_| management || dst != 9)
            .map(|len| mpdu[..len].to_vec());
            prop_assert_eq!(board.board.out.first(), general.as_ref());
            prop_assert_eq!(board.board.out.len(), usize::from(general.is_some()));
            prop_assert_eq!(node.radio.mac_seq, seq.wrapping_add(1));
            prop_assert_eq!(board.counter, sent);
        }
    }

    /// The secured short path takes a peer's secured event or ack to this node (accepted,
    /// challenged, replayed, forged alike) and a peer's challenge answer it opened, and
    /// leaves every other frame to the general path.
    #[test]
    fn the_secured_short_path_takes_a_peers_secured_frames_to_this_node() {
        let mut node =
            NodeCore::new(B, 1 << 5 | 1 << 7, Some(table_b(false)), 1).with_link_keys(keys_b(0));
        let mut board = Counting::default();
        let frame = |msg: SecuredMsg, counter: u32, out: &[std::vec::Vec<u8>]| {
            let f = Secured {
                src: A,
                dst: B,
                ack_request: false,
                msg,
                generation: 0,
                index: None,
                counter,
                wrong_key: false,
                damage: None,
            };
            f.mpdu(out, 0)
        };
        let event = |seq| {
            SecuredMsg::Link(LinkMessage::Event {
                epoch: 0,
                seq,
                topic: 3,
            })
        };
        // No floor for A yet: challenged, not acted on.
        let first = frame(event(0), 10, &board.board.out);
        assert!(node.link_secured(&first, 0, &mut board));
        assert_eq!(node.radio.security.challenged, 1);
        assert!(board.board.pins.is_empty());
        assert_eq!(last_challenge(&board.board.out, A, 0), Some(1));
        // A's answer, opened once, sets the floor.
        let answer = frame(SecuredMsg::Answer, 11, &board.board.out);
        assert!(node.link_secured(&answer, 0, &mut board));
        // The event now runs the chart and is acknowledged.
        let sent = board.board.out.len();
        let again = frame(event(0), 12, &board.board.out);
        assert!(node.link_secured(&again, 0, &mut board));
        assert_eq!(board.board.pins, [(7, true)]);
        assert_eq!(board.board.out.len(), sent + 1);
        // (The answer is the handshake's, not counted as received.)
        assert_eq!(node.radio.counters.received, 1);
        // Replayed, and forged: refused and counted here.
        assert!(node.link_secured(&again, 0, &mut board));
        assert_eq!(node.radio.security.replayed, 1);
        let mut forged = frame(event(1), 13, &board.board.out);
        let last = forged.len() - 1;
        forged[last] ^= 1;
        assert!(node.link_secured(&forged, 0, &mut board));
        assert_eq!(node.radio.security.bad_mic, 1);
        assert_eq!(node.radio.counters.dropped, 2);
        // Not this path's: broadcast, from this node itself, under a key index it has no
        // key for, in clear.
        let other = |src: u16, dst: u16, index: Option<u8>| Secured {
            src,
            dst,
            ack_request: false,
            msg: event(2),
            generation: 0,
            index,
            counter: 20,
            wrong_key: false,
            damage: None,
        };
        for f in [
            other(A, BROADCAST, None),
            other(B, B, None),
            other(A, B, Some(security::link_key_index(7))),
        ] {
            assert!(!node.link_secured(&f.mpdu(&[], 0), 0, &mut board), "{f:?}");
        }
        let mut clear = first.clone();
        clear.truncate(mac::DATA_HEADER_LEN);
        assert!(!node.link_secured(&clear, 0, &mut board));
    }

    /// The short path takes the frames it is for, and only those.
    #[test]
    fn the_short_path_takes_an_unsecured_event_to_this_node() {
        let mut node = NodeCore::new(B, 1 << 5 | 1 << 7, Some(table_b(false)), 1);
        let mut board = Board::default();
        let event = |fc: u16, dst: u16| mpdu(fc, 0, [PAN, dst, A], &[0, 0, 0, 3]);
        assert!(node.link_in_clear(&event(mac::PLAIN_DATA_FC, B), 0, &mut board));
        assert_eq!(board.pins, [(7, true)]);
        assert_eq!(board.out.len(), 1);
        assert!(!node.link_in_clear(&event(mac::PLAIN_DATA_FC, BROADCAST), 0, &mut board));
        assert!(!node.link_in_clear(&event(mac::PLAIN_DATA_FC | 1 << 3, B), 0, &mut board));
        assert!(!node.link_in_clear(&event(mac::PLAIN_DATA_FC | 1 << 5, B), 0, &mut board));
        // The frame as the node writes it starts with the control field compared.
        let fc = u16::from_le_bytes([board.out[0][0], board.out[0][1]]);
        assert_eq!(fc, mac::PLAIN_DATA_FC);
    }

    /// An ack through [`Senders::with`] keeps the cached alarm bits exactly what a count gives.
    #[test]
    fn senders_ack_keeps_the_alarm_cache_right() {
        let mut s = Senders::default();
        for _ in 0..2 {
            s.push(link::Sender::new(0)).ok().unwrap();
        }
        let mut now = 0;
        s[1].push(7, now, |_| {}).unwrap();
        assert_eq!(s.alarms(), 0);
        // No acknowledgement: the link to peer 1 goes into alarm.
        while s.list[1].state() != LinkState::Alarm {
            now = s.list[1].deadline().unwrap();
            s[1].poll(now, |_| {});
        }
        assert_eq!(s.alarms(), 0b10);
        // An ack that is not about this window changes nothing.
        s.with(1, |x| x.on_ack(1, 1, now, |_| {}));
        assert!(!s.touched);
        assert_eq!(s.alarms(), links_in(&s.list, LinkState::Alarm));
        assert_eq!(s.alarms(), 0b10);
        // The ack for it ends the alarm, without a count.
        s.with(1, |x| x.on_ack(0, 1, now, |_| {}));
        assert!(!s.touched);
        assert_eq!(s.alarms(), links_in(&s.list, LinkState::Alarm));
        assert_eq!(s.alarms(), 0);
        // No such peer: nothing.
        s.with(5, |x| x.on_ack(0, 1, now, |_| {}));
        assert_eq!(s.alarms(), 0);
        assert_eq!(s.with(5, |_| ()), None);
        // A push through `with` keeps the cache right, without a count.
        let mut sent = 0;
        s.with(0, |x| x.push(3, now, |_| sent += 1))
            .unwrap()
            .unwrap();
        assert_eq!(sent, 1);
        assert!(!s.touched);
        assert_eq!(s.alarms(), links_in(&s.list, LinkState::Alarm));
        // And so does a poll that puts the link into alarm.
        while s.list[0].state() != LinkState::Alarm {
            let at = s.list[0].deadline().unwrap();
            s.with(0, |x| x.poll(at, |_| {}));
            assert!(!s.touched);
            assert_eq!(s.alarms(), links_in(&s.list, LinkState::Alarm));
        }
        assert_eq!(s.alarms(), 0b01);
    }
}
