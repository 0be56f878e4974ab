//! A world and its scheduler, ready to run: the rig and the firmware, with
//! or without the machine.

use super::sources::{add_machine_sources, WorldTick};
use super::world::FirmwareWorld;
use crate::machine::MachineConfig;
use crate::plant::RigConfig;
use crate::sched::Scheduler;
use zslide::servo::ServoConfig;

/// Rig + firmware at `loop_hz` with the loop-tick source registered (index
/// [`super::sources::src::LOOP_TICK`]).
pub fn firmware_demo(cfg: RigConfig, loop_hz: u32) -> (FirmwareWorld, Scheduler<FirmwareWorld>) {
    let loop_cfg = ServoConfig::at_rate(loop_hz)
        .expect("the default loop design holds at the rig rates (8 kHz..200 kHz)");
    firmware_with(cfg, loop_hz, loop_cfg)
}

/// [`firmware_demo`] with a given loop configuration.
pub fn firmware_with(
    cfg: RigConfig,
    loop_hz: u32,
    loop_cfg: ServoConfig,
) -> (FirmwareWorld, Scheduler<FirmwareWorld>) {
    let w = FirmwareWorld::new(cfg, loop_cfg);
    let mut s = Scheduler::new();
    let period = 1_000_000_000 / u64::from(loop_hz.max(1));
    s.add(WorldTick::loop_tick(period));
    (w, s)
}

/// [`firmware_demo`] with the X slide and spindle attached and their
/// interrupt sources registered (after the loop tick).
pub fn machine_demo(
    cfg: RigConfig,
    machine: &MachineConfig,
    loop_hz: u32,
) -> (FirmwareWorld, Scheduler<FirmwareWorld>) {
    let loop_cfg = ServoConfig::at_rate(loop_hz)
        .expect("the default loop design holds at the rig rates (8 kHz..200 kHz)");
    machine_with(cfg, machine, loop_hz, loop_cfg)
}

/// [`machine_demo`] with a given loop configuration.
pub fn machine_with(
    cfg: RigConfig,
    machine: &MachineConfig,
    loop_hz: u32,
    loop_cfg: ServoConfig,
) -> (FirmwareWorld, Scheduler<FirmwareWorld>) {
    machine_with_table(cfg, machine, loop_hz, loop_cfg, zslide::DEFAULT_TABLE)
}

/// [`machine_with`] with another coefficient table image.
pub fn machine_with_table(
    cfg: RigConfig,
    machine: &MachineConfig,
    loop_hz: u32,
    loop_cfg: ServoConfig,
    table: &'static [u8],
) -> (FirmwareWorld, Scheduler<FirmwareWorld>) {
    let (mut w, mut s) = firmware_with(cfg, loop_hz, loop_cfg);
    w.attach_machine_with_table(machine, table);
    add_machine_sources(&w, &mut s);
    (w, s)
}
