//! Where the interpreter finds a table's pieces, worked out once per table (at activation)
//! so that a stimulus follows short chains instead of scanning the table's pools: the
//! routes of each event, the transitions leaving each state (in declaration order), each
//! event's publication, and which states have event-less transitions.
//!
//! Derived data only: the table stays the one validated form, and an index built from it
//! gives exactly the order the pools have (the first matching transition in declaration
//! order, the routes in table order). Built without panics from any table: an entry that
//! points outside the pools is left out (validation refuses such tables anyway).

use config_schema::limits::{MAX_CHARTS, MAX_EVENTS, MAX_ROUTES, MAX_STATES, MAX_TRANSITIONS};
use config_schema::Table;

/// The end of a chain.
pub(super) const NONE: u8 = u8::MAX;

// Every pool index fits a `u8` below `NONE`, and a state set fits a `u128`.
const _: () = assert!(MAX_ROUTES < NONE as usize);
const _: () = assert!(MAX_TRANSITIONS < NONE as usize);
const _: () = assert!(MAX_EVENTS <= NONE as usize);
const _: () = assert!(MAX_STATES <= 128);

/// Where a chart's pieces are in the table's pools.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub(super) struct Layout {
    /// Its first state in `Table::states` (chart-local state `s` is `first_state + s`).
    pub first_state: u8,
    /// Its number of states.
    pub states: u8,
}

/// A table's index: chains through its pools, built once by [`Index::new`].
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Index {
    pub(super) layout: [Layout; MAX_CHARTS],
    /// Per event: its first route (`NONE`: none); `next_route` chains the rest in order.
    first_route: [u8; MAX_EVENTS],
    next_route: [u8; MAX_ROUTES],
    /// Per global state: the first transition leaving it; `next_from` chains the rest in
    /// declaration order.
    first_from: [u8; MAX_STATES],
    next_from: [u8; MAX_TRANSITIONS],
    /// Per event: its publication's index (`NONE`: not published).
    publication: [u8; MAX_EVENTS],
    /// Bit s: global state s has an event-less transition leaving it.
    eventless: u128,
}

impl Index {
    /// The index of `table`.
    pub fn new(table: &Table) -> Index {
        let mut ix = Index {
            layout: [Layout::default(); MAX_CHARTS],
            first_route: [NONE; MAX_EVENTS],
            next_route: [NONE; MAX_ROUTES],
            first_from: [NONE; MAX_STATES],
            next_from: [NONE; MAX_TRANSITIONS],
            publication: [NONE; MAX_EVENTS],
            eventless: 0,
        };
        for (c, slot) in ix.layout.iter_mut().enumerate().take(table.charts.len()) {
            let states = table.chart_states(c);
            *slot = Layout {
                first_state: states.start as u8,
                states: states.len() as u8,
            };
        }
        // Chains are built back to front, so each lists its entries in pool order.
        for (r, route) in table.routes.iter().enumerate().take(MAX_ROUTES).rev() {
            if let Some(first) = ix.first_route.get_mut(usize::from(route.event)) {
                if let Some(next) = ix.next_route.get_mut(r) {
                    *next = *first;
                    *first = r as u8;
                }
            }
        }
        for c in (0..table.charts.len().min(MAX_CHARTS)).rev() {
            let Layout {
                first_state,
                states,
            } = ix.layout[c];
            let range = table.chart_transitions(c);
            let Some(ts) = table.transitions.get(range.clone()) else {
                continue;
            };
            for (i, t) in ts.iter().enumerate().rev() {
                let global = range.start + i;
                if t.from >= states || global >= MAX_TRANSITIONS {
                    continue;
                }
                let state = usize::from(first_state) + usize::from(t.from);
                if let Some(first) = ix.first_from.get_mut(state) {
                    ix.next_from[global] = *first;
                    *first = global as u8;
                    if t.trigger.is_none() {
                        ix.eventless |= 1u128 << state;
                    }
                }
            }
        }
        for (p, publication) in table.publications.iter().enumerate().rev() {
            if let Some(slot) = ix.publication.get_mut(usize::from(publication.event)) {
                *slot = p as u8;
            }
        }
        ix
    }

    /// The first route of `event` (`NONE`: none).
    #[inline]
    pub(super) fn first_route(&self, event: u8) -> u8 {
        self.first_route
            .get(usize::from(event))
            .copied()
            .unwrap_or(NONE)
    }

    /// The route after `route` of the same event (`NONE`: the last).
    #[inline]
    pub(super) fn next_route(&self, route: u8) -> u8 {
        self.next_route
            .get(usize::from(route))
            .copied()
            .unwrap_or(NONE)
    }

    /// The first transition leaving global state `state` (`NONE`: none).
    #[inline]
    pub(super) fn first_from(&self, state: usize) -> u8 {
        self.first_from.get(state).copied().unwrap_or(NONE)
    }

    /// The transition after `transition` leaving the same state (`NONE`: the last).
    #[inline]
    pub(super) fn next_from(&self, transition: u8) -> u8 {
        self.next_from
            .get(usize::from(transition))
            .copied()
            .unwrap_or(NONE)
    }

    /// The index of `event`'s publication (`NONE`: not published).
    #[inline]
    pub(super) fn publication(&self, event: u8) -> u8 {
        self.publication
            .get(usize::from(event))
            .copied()
            .unwrap_or(NONE)
    }

    /// Whether global state `state` has an event-less transition leaving it.
    #[inline]
    pub(super) fn eventless(&self, state: usize) -> bool {
        state < 128 && self.eventless & (1u128 << state) != 0
    }
}
