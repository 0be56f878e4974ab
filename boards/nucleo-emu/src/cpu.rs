//! The Cortex-M7 core: unicorn executes the Thumb-2 and FPU instructions
//! (its Cortex-M7 model); the exception model is here, as ARMv7-M
//! specifies it (B1.5): entry pushes the basic frame, or the extended one
//! with S0-S15 and FPSCR when CONTROL.FPCA is set, aligned to 8 bytes,
//! loads EXC_RETURN into LR and the handler from the vector table at
//! VTOR; a return (a branch to EXC_RETURN) tail-chains into a pending
//! exception that may preempt the one returned to, or pops the frame.
//! Unicorn keeps the core in thread mode throughout (IPSR 0), so a branch
//! to EXC_RETURN is an instruction fetch from 0xFFFF_FFxx, which stops it
//! and lands here.
//!
//! Time: one instruction is one cycle of the system clock the RCC model
//! sets (64 MHz HSI until the switch, 400 MHz after). The M7's dual issue,
//! flash wait states and cache hits are not modelled: instruction counts,
//! not cycle counts (docs/BOARD.md says what that does not prove).

use unicorn_engine::unicorn_const::{uc_error, Arch, Mode, Permission};
use unicorn_engine::{RegisterARM, Unicorn};

use crate::board::{Board, IRQ_TIM3, PPB};
use crate::flash::{BANK2_BASE, BANK2_SIZE};

/// The H743's memories (RM0433 table 7): (base, size).
pub const ITCM: (u32, usize) = (0x0000_0000, 64 << 10);
pub const BANK1: (u32, usize) = (0x0800_0000, 1 << 20);
pub const DTCM: (u32, usize) = (0x2000_0000, 128 << 10);
pub const AXI_SRAM: (u32, usize) = (0x2400_0000, 512 << 10);
/// SRAM1, SRAM2, SRAM3 (contiguous in D2).
pub const SRAM123: (u32, usize) = (0x3000_0000, 288 << 10);
pub const SRAM4: (u32, usize) = (0x3800_0000, 64 << 10);
pub const BACKUP_SRAM: (u32, usize) = (0x3880_0000, 4 << 10);

extern "C" {
    fn uc_ctl(uc: *mut libc::c_void, control: u32, ...) -> uc_error;
}
/// `UC_CTL_WRITE(UC_CTL_CPU_MODEL, 1)` and `UC_CPU_ARM_CORTEX_M7`
/// (unicorn.h, arm.h of 2.0.1).
const UC_CTL_CPU_MODEL_WRITE: u32 = 7 | (1 << 26) | (1 << 30);
const UC_CPU_ARM_CORTEX_M7: i32 = 10;
/// QEMU's internal exception number for a branch to EXC_RETURN, which
/// unicorn reports through its interrupt hook.
const EXCP_EXCEPTION_EXIT: u32 = 8;

pub struct Cpu<'a> {
    pub uc: Unicorn<'a, Board>,
}

fn r(uc: &Unicorn<Board>, reg: RegisterARM) -> u32 {
    uc.reg_read(reg).unwrap_or(0) as u32
}
fn w(uc: &mut Unicorn<Board>, reg: RegisterARM, v: u32) {
    let _ = uc.reg_write(reg, u64::from(v));
}
fn rd32(uc: &Unicorn<Board>, a: u32) -> u32 {
    let mut b = [0u8; 4];
    let _ = uc.mem_read(u64::from(a), &mut b);
    u32::from_le_bytes(b)
}
fn wr32(uc: &mut Unicorn<Board>, a: u32, v: u32) -> Result<(), String> {
    uc.mem_write(u64::from(a), &v.to_le_bytes())
        .map_err(|e| format!("exception frame write at {a:#010x}: {e:?} (stack overflow?)"))
}

const S_REGS: [RegisterARM; 16] = [
    RegisterARM::S0,
    RegisterARM::S1,
    RegisterARM::S2,
    RegisterARM::S3,
    RegisterARM::S4,
    RegisterARM::S5,
    RegisterARM::S6,
    RegisterARM::S7,
    RegisterARM::S8,
    RegisterARM::S9,
    RegisterARM::S10,
    RegisterARM::S11,
    RegisterARM::S12,
    RegisterARM::S13,
    RegisterARM::S14,
    RegisterARM::S15,
];

impl<'a> Cpu<'a> {
    /// The core with the memory map, the image loaded and the models
    /// attached; reset (SP and PC from the vector table at `vtor`).
    pub fn new(board: Board, segments: &[(u32, Vec<u8>)], vtor: u32) -> Result<Self, String> {
        let mut uc = Unicorn::new_with_data(Arch::ARM, Mode::THUMB | Mode::MCLASS, board)
            .map_err(|e| format!("unicorn: {e:?}"))?;
        // SAFETY: uc_ctl with CPU_MODEL takes one int; it is called before
        // any other use of the engine, as unicorn requires.
        let e = unsafe {
            uc_ctl(
                uc.get_handle(),
                UC_CTL_CPU_MODEL_WRITE,
                UC_CPU_ARM_CORTEX_M7,
            )
        };
        if e != uc_error::OK {
            return Err(format!("unicorn: cannot select the Cortex-M7 model: {e:?}"));
        }
        let rwx = Permission::ALL;
        for (base, size, perms) in [
            (ITCM.0, ITCM.1, rwx),
            (BANK1.0, BANK1.1, Permission::READ | Permission::EXEC),
            (DTCM.0, DTCM.1, rwx),
            (AXI_SRAM.0, AXI_SRAM.1, rwx),
            (SRAM123.0, SRAM123.1, rwx),
            (SRAM4.0, SRAM4.1, rwx),
            (BACKUP_SRAM.0, BACKUP_SRAM.1, rwx),
        ] {
            uc.mem_map(u64::from(base), size, perms)
                .map_err(|e| format!("map {base:#010x}: {e:?}"))?;
        }
        for (base, size) in [
            (BANK2_BASE as u64, BANK2_SIZE),
            // APB1/APB2/AHB1/AHB2 peripherals, then D3/D1 (APB3, AHB3 with
            // FLASH, AHB4 with RCC/PWR/GPIO, APB4, DBGMCU).
            (0x4000_0000, 0x1000_0000),
            (0x5000_0000, 0x0C00_2000),
            (PPB as u64, 0x10_0000),
        ] {
            uc.mmio_map(
                base,
                size,
                Some(move |uc: &mut Unicorn<Board>, off: u64, sz: usize| {
                    u64::from(uc.get_data_mut().read((base + off) as u32, sz))
                }),
                Some(
                    move |uc: &mut Unicorn<Board>, off: u64, sz: usize, v: u64| {
                        uc.get_data_mut().write((base + off) as u32, sz, v as u32);
                    },
                ),
            )
            .map_err(|e| format!("mmio {base:#x}: {e:?}"))?;
        }
        for (addr, data) in segments {
            uc.mem_write(u64::from(*addr), data)
                .map_err(|e| format!("load {} bytes at {addr:#010x}: {e:?}", data.len()))?;
        }
        // Bank 1's halfwords: a block's instructions are counted by their
        // encodings (a first halfword 0b11101/0b11110/0b11111 is a 32-bit
        // instruction), and a WFI (0xBF30) ending a block puts the core
        // to sleep.
        let mut code = vec![0u16; BANK1.1 / 2];
        for (addr, data) in segments {
            if !(BANK1.0..BANK1.0 + BANK1.1 as u32).contains(addr) {
                continue;
            }
            let o = ((addr - BANK1.0) / 2) as usize;
            for (i, hw) in data.chunks_exact(2).enumerate() {
                code[o + i] = u16::from_le_bytes([hw[0], hw[1]]);
            }
        }
        // A stop requested from a block hook takes effect before that block
        // runs (PC is its first instruction): so the stop is checked before
        // the block's instructions are counted, and a WFI is known to have
        // run when the next block starts right after it.
        uc.add_block_hook(move |uc: &mut Unicorn<Board>, addr: u64, size: u32| {
            let (a, size) = (addr as u32, size as usize);
            let b = uc.get_data_mut();
            if b.wfi_ran.take().is_some_and(|w| w.wrapping_add(2) == a) {
                b.sleeping = true;
                let _ = uc.emu_stop();
                return;
            }
            if b.t >= b.until {
                let _ = uc.emu_stop();
                return;
            }
            let (mut n, mut last) = (0u64, None);
            if a.wrapping_sub(BANK1.0) < BANK1.1 as u32 {
                let mut i = ((a - BANK1.0) / 2) as usize;
                let end = i + size / 2;
                while i < end && i < code.len() {
                    n += 1;
                    last = Some(i);
                    i += if code[i] >> 11 >= 0b11101 { 2 } else { 1 };
                }
            } else {
                n = (size / 2) as u64;
            }
            b.instructions += n;
            b.t += n * b.cycle_ps;
            b.wfi_ran = last
                .filter(|&i| code[i] == 0xBF30)
                .map(|i| BANK1.0 + 2 * i as u32);
        })
        .map_err(|e| format!("hook: {e:?}"))?;
        uc.add_intr_hook(|uc: &mut Unicorn<Board>, intno: u32| {
            let pc = uc.reg_read(RegisterARM::PC).unwrap_or(0);
            if intno == EXCP_EXCEPTION_EXIT && pc >= 0xFFFF_FF00 {
                // A branch to EXC_RETURN: ours to complete.
                let _ = uc.emu_stop();
                return;
            }
            let b = uc.get_data_mut();
            if b.violation.is_none() {
                b.violation = Some(format!(
                    "CPU exception {intno} (unicorn's number) at pc {pc:#010x}: an undefined instruction (udf: the panic handler), or a fault"
                ));
            }
            let _ = uc.emu_stop();
        })
        .map_err(|e| format!("hook: {e:?}"))?;
        let sp = rd32(&uc, vtor);
        let pc = rd32(&uc, vtor + 4);
        w(&mut uc, RegisterARM::SP, sp);
        w(&mut uc, RegisterARM::PC, pc & !1);
        Ok(Self { uc })
    }

    pub fn board(&mut self) -> &mut Board {
        self.uc.get_data_mut()
    }

    /// The priority the core executes at: the highest active exception's,
    /// 0 with PRIMASK set (only NMI and HardFault above), BASEPRI.
    fn exec_priority(&self, active: &[u32]) -> i32 {
        let b = self.uc.get_data();
        let mut p = active
            .iter()
            .map(|&n| i32::from(b.scs.priority(n)))
            .min()
            .unwrap_or(256);
        if r(&self.uc, RegisterARM::PRIMASK) & 1 != 0 {
            p = p.min(0);
        }
        let basepri = r(&self.uc, RegisterARM::BASEPRI) & 0xF0;
        if basepri != 0 {
            p = p.min(basepri as i32);
        }
        p
    }

    /// The pending, enabled interrupt that would preempt `active` now.
    fn preempting(&self, active: &[u32]) -> Option<u32> {
        let b = self.uc.get_data();
        let exec = self.exec_priority(active);
        let mut best: Option<(u8, u32)> = None;
        for irq in 0..crate::scs::IRQS {
            if b.scs.pending[irq] && b.scs.enabled[irq] {
                let n = 16 + irq as u32;
                let p = b.scs.priority(n);
                if i32::from(p) < exec && best.is_none_or(|(bp, _)| p < bp) {
                    best = Some((p, n));
                }
            }
        }
        best.map(|(_, n)| n)
    }

    /// Wakes from WFI on any pending enabled interrupt (PRIMASK or not).
    fn wake_pending(&self) -> bool {
        let b = self.uc.get_data();
        (0..crate::scs::IRQS).any(|i| b.scs.pending[i] && b.scs.enabled[i])
    }

    fn enter(&mut self, n: u32, exc_return: Option<u32>) -> Result<(), String> {
        let uc = &mut self.uc;
        let lr = match exc_return {
            Some(lr) => lr, // tail-chained: the frame stays
            None => {
                let control = r(uc, RegisterARM::CONTROL);
                let fpca = control & 0b100 != 0 && uc.get_data().scs.fpu_enabled();
                let handler = !uc.get_data().active.is_empty();
                let sp = r(uc, RegisterARM::SP);
                let size = if fpca { 0x68 } else { 0x20 };
                let align = (sp - size) & 4;
                let frame = (sp - size) & !7;
                let mut xpsr = r(uc, RegisterARM::XPSR) & !0x1FF & !(1 << 9);
                xpsr |= u32::from(align != 0) << 9;
                let pc = r(uc, RegisterARM::PC);
                let regs = [
                    r(uc, RegisterARM::R0),
                    r(uc, RegisterARM::R1),
                    r(uc, RegisterARM::R2),
                    r(uc, RegisterARM::R3),
                    r(uc, RegisterARM::R12),
                    r(uc, RegisterARM::LR),
                    pc,
                    xpsr | (1 << 24),
                ];
                for (i, v) in regs.iter().enumerate() {
                    wr32(uc, frame + 4 * i as u32, *v)?;
                }
                if fpca {
                    for (i, s) in S_REGS.iter().enumerate() {
                        let v = r(uc, *s);
                        wr32(uc, frame + 0x20 + 4 * i as u32, v)?;
                    }
                    let fpscr = r(uc, RegisterARM::FPSCR);
                    wr32(uc, frame + 0x60, fpscr)?;
                }
                let psp = !handler && control & 0b10 != 0;
                // Handler mode runs on MSP with FPCA clear.
                w(uc, RegisterARM::SP, frame);
                w(uc, RegisterARM::CONTROL, control & !0b110);
                let mut lr = if handler {
                    0xFFFF_FFF1
                } else if psp {
                    0xFFFF_FFFD
                } else {
                    0xFFFF_FFF9
                };
                if fpca {
                    lr &= !(1 << 4);
                }
                lr
            }
        };
        let b = uc.get_data_mut();
        b.active.push(n);
        if n >= 16 {
            b.scs.pending[(n - 16) as usize] = false;
        }
        if n == 16 + IRQ_TIM3 as u32 {
            if let Some(at) = b.stats.tim3_pended_at.take() {
                b.stats.max_tick_latency_ps =
                    b.stats.max_tick_latency_ps.max(b.t.saturating_sub(at));
            }
            b.stats.loop_ticks += 1;
        }
        let vtor = b.scs.vtor;
        let handler = rd32(uc, vtor + 4 * n);
        w(uc, RegisterARM::LR, lr);
        w(uc, RegisterARM::PC, handler & !1);
        Ok(())
    }

    fn exception_return(&mut self, exc_return: u32) -> Result<(), String> {
        let active = {
            let b = self.uc.get_data_mut();
            if b.active.pop().is_none() {
                return Err(format!(
                    "branch to EXC_RETURN {exc_return:#010x} in thread mode"
                ));
            }
            b.active.clone()
        };
        self.uc.get_data_mut().lines();
        if let Some(n) = self.preempting(&active) {
            return self.enter(n, Some(exc_return)); // tail-chaining
        }
        let uc = &mut self.uc;
        let to_thread = exc_return & 0b1000 != 0;
        let psp = to_thread && exc_return & 0b100 != 0;
        let fp = exc_return & 0b1_0000 == 0;
        let mut control = r(uc, RegisterARM::CONTROL) & !0b110;
        if psp {
            control |= 0b10;
        }
        w(uc, RegisterARM::CONTROL, control);
        let frame = r(uc, RegisterARM::SP);
        let v: Vec<u32> = (0..8).map(|i| rd32(uc, frame + 4 * i)).collect();
        for (reg, x) in [
            RegisterARM::R0,
            RegisterARM::R1,
            RegisterARM::R2,
            RegisterARM::R3,
            RegisterARM::R12,
            RegisterARM::LR,
        ]
        .iter()
        .zip(&v)
        {
            w(uc, *reg, *x);
        }
        let mut size = 0x20;
        if fp {
            for (i, s) in S_REGS.iter().enumerate() {
                let x = rd32(uc, frame + 0x20 + 4 * i as u32);
                w(uc, *s, x);
            }
            let fpscr = rd32(uc, frame + 0x60);
            w(uc, RegisterARM::FPSCR, fpscr);
            size = 0x68;
        }
        if v[7] & (1 << 9) != 0 {
            size += 4;
        }
        w(
            uc,
            RegisterARM::XPSR,
            (v[7] & !0x1FF & !(1 << 9)) | (1 << 24),
        );
        w(
            uc,
            RegisterARM::CONTROL,
            control | if fp { 0b100 } else { 0 },
        );
        w(uc, RegisterARM::SP, frame + size);
        w(uc, RegisterARM::PC, v[6] & !1);
        Ok(())
    }

    /// Runs until emulated time `end` or a stop; the reason if stopped.
    pub fn run(&mut self, end: u64, mut between: impl FnMut(&mut Self)) -> Option<String> {
        loop {
            {
                let b = self.board();
                b.events();
                if b.scs.reset_requested {
                    return Some("system reset requested (SCB_AIRCR.SYSRESETREQ)".into());
                }
            }
            if let Some(v) = self.board().violation.clone() {
                return Some(v);
            }
            between(self);
            let t = self.board().t;
            if t >= end {
                return None;
            }
            if self.board().sleeping {
                if self.wake_pending() {
                    self.board().sleeping = false;
                } else {
                    let next = self.board().next_event().min(end);
                    self.board().t = next;
                    continue;
                }
            }
            let active = self.board().active.clone();
            if let Some(n) = self.preempting(&active) {
                if let Err(e) = self.enter(n, None) {
                    return Some(e);
                }
            }
            let next = self.board().next_event().min(end);
            self.board().until = next;
            let pc = r(&self.uc, RegisterARM::PC);
            self.board().stats.slices += 1;
            let res = self.uc.emu_start(u64::from(pc | 1), 0, 0, 0);
            let pc = r(&self.uc, RegisterARM::PC);
            if pc >= 0xFFFF_FF00 {
                if let Err(e) = self.exception_return(pc | 1) {
                    return Some(e);
                }
                continue;
            }
            match res {
                Ok(()) => {
                    // Unicorn ends a run at a WFI it executed (its halt).
                    let b = self.board();
                    if b.wfi_ran.is_some_and(|w| w.wrapping_add(2) == pc) {
                        b.wfi_ran = None;
                        b.sleeping = true;
                    }
                }
                Err(uc_error::FETCH_UNMAPPED | uc_error::FETCH_PROT) if pc >= 0xFFFF_FF00 => {
                    if let Err(e) = self.exception_return(pc | 1) {
                        return Some(e);
                    }
                }
                Err(e) => {
                    if let Some(v) = self.board().violation.clone() {
                        return Some(v);
                    }
                    return Some(format!("CPU stopped: {e:?} at pc {pc:#010x}"));
                }
            }
        }
    }
}
