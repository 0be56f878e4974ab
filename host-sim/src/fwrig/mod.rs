//! The firmware on the simulated machine, end to end: the core's own
//! drivers (`zslide::drivers::{Ad5791, Ad4020}`) on the simulated chips, the
//! core's `Firmware::loop_tick`, and (optionally) the X slide and spindle
//! through the core's `hw` traits with their interrupts delivered by the
//! scheduler at their exact instants.
//!
//! Event sources and priorities (`sched::prio`): loop tick (timer, CNV then
//! the handler) > X half-mil interrupt > index pulse. The plant is advanced
//! exactly to each event before it runs (`World::advance_to`).
//!
//! With a machine attached the firmware is the integrated one
//! (`Firmware::with_table(DEFAULT_TABLE, ..)`): the X half-mil interrupt
//! calls `Firmware::x_event` (with the core's AD5686 driver on the simulated
//! quad DAC for the legacy coefficient output), the index calls
//! `Firmware::index_event`, and the loop tick gets its `TickInput` from the
//! hw-trait implementations (`Encoder`, `Tachometer`, `Clock`). The
//! firmware keeps its spindle angle private, so the world runs a monitor
//! copy of the core's estimator on the same readings to report it.
//!
//! The folder: the world ([`world`]: rig, firmware, handlers, the tick's
//! hooks), the machine attached to it ([`attached`]), its event sources
//! ([`sources`]), the host link ([`link`]), who drives the amplifier
//! ([`controller`]) and the builders of a ready world ([`builders`]).

pub mod attached;
pub mod builders;
pub mod controller;
pub mod link;
pub mod sources;
pub mod world;

pub use attached::{Machine, MachineStats};
pub use builders::{firmware_demo, firmware_with, machine_demo, machine_with, machine_with_table};
pub use controller::Controller;
pub use link::HostLink;
pub use sources::{add_machine_sources, src, IndexSource, WorldTick, XHalfMilSource};
pub use world::{Cpu, FirmwareWorld, TickHook};
