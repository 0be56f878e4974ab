//! `cargo xtask no-panic`: proves from the linked images that no panic path
//! is reachable from an interrupt or exception handler.
//!
//! With LTO and `--gc-sections` a panicking function of `core` survives in
//! the ELF only if something calls it, and its callers are found by
//! decoding the Thumb code itself (no binutils): the check builds the call
//! graph of every function symbol from its direct branches (BL, B.W, B<c>.W,
//! B, B<c>, CBZ/CBNZ leaving the function), starts from every handler in the
//! vector table except Reset (boot code, thread mode) and HardFault (the
//! last-resort fault path: it makes the outputs safe before anything else),
//! and fails if any panicking function is reachable. One thread-mode
//! function is held to the same rule: the host link's service
//! (`Station::poll`), which takes whatever bytes a host sends.
//!
//! Indirect calls (BLX Rm, BX Rm other than LR, MOV PC / LDR PC) cannot be
//! followed, so they are over-approximated: a reachable function that makes
//! one may call every function whose address appears as a word anywhere in
//! the image. Literal pools are skipped with the ELF's `$d`/`$t` mapping
//! symbols, so data is never decoded as a branch.

use std::collections::VecDeque;
use std::path::Path;

use crate::elf::{self, Image};

/// Mangled-name fragments of everything that panics or only exists to
/// panic: `core::panicking::*` (panic, panic_fmt, panic_bounds_check,
/// panic_const_*, ...), the slice/str index failures, Option/Result
/// unwrap/expect failures, RefCell borrow failures, and the panic handler
/// itself (`rust_begin_unwind`, what `#[panic_handler]` is linked as).
const PANICKING: &[&str] = &[
    "panicking",
    "panic_fmt",
    "panic_bounds_check",
    "panic_const",
    "panic_already",
    "rust_begin_unwind",
    "unwrap_failed",
    "expect_failed",
    "index_order_fail",
    "index_len_fail",
    "start_index_len_fail",
    "end_index_len_fail",
    "str_index_overflow_fail",
    "slice_error_fail",
];

pub fn is_panicking(name: &str) -> bool {
    PANICKING.iter().any(|p| name.contains(p))
}

#[derive(Debug)]
pub struct Func {
    pub name: String,
    pub start: u32,
    pub end: u32,
}

/// Branches out of one function's code.
#[derive(Debug, Default, PartialEq, Eq)]
pub struct Branches {
    /// Direct branch targets (Thumb bit clear).
    pub targets: Vec<u32>,
    /// Whether it makes an indirect call or jump.
    pub indirect: bool,
}

fn sext(v: u32, bits: u32) -> i32 {
    let shift = 32 - bits;
    ((v << shift) as i32) >> shift
}

/// Decodes Thumb-2 code at `addr`; `is_data(a)` says whether the halfword
/// at `a` lies in a literal pool.
pub fn decode(addr: u32, code: &[u8], is_data: &dyn Fn(u32) -> bool) -> Branches {
    let mut out = Branches::default();
    let hw = |i: usize| -> Option<u32> {
        Some(u32::from(u16::from_le_bytes([
            *code.get(i)?,
            *code.get(i + 1)?,
        ])))
    };
    let mut i = 0usize;
    while let Some(h1) = hw(i) {
        let pc = addr.wrapping_add(i as u32);
        if is_data(pc) {
            i += 2;
            continue;
        }
        let wide = matches!(h1 >> 11, 0b11101..=0b11111);
        if !wide {
            if h1 >> 11 == 0b11100 {
                // B (T2)
                let off = sext((h1 & 0x7FF) << 1, 12);
                out.targets
                    .push(pc.wrapping_add(4).wrapping_add_signed(off));
            } else if h1 >> 12 == 0b1101 && (h1 >> 8) & 0xF < 0b1110 {
                // B<c> (T1)
                let off = sext((h1 & 0xFF) << 1, 9);
                out.targets
                    .push(pc.wrapping_add(4).wrapping_add_signed(off));
            } else if h1 & 0xF500 == 0xB100 {
                // CBZ / CBNZ
                let off = ((h1 >> 9) & 1) << 6 | ((h1 >> 3) & 0x1F) << 1;
                out.targets.push(pc.wrapping_add(4).wrapping_add(off));
            } else if h1 & 0xFF80 == 0x4780 {
                out.indirect = true; // BLX Rm
            } else if h1 & 0xFF80 == 0x4700 && (h1 >> 3) & 0xF != 14 {
                out.indirect = true; // BX Rm, not a return
            } else if h1 & 0xFF87 == 0x4687 {
                out.indirect = true; // MOV PC, Rm
            }
            i += 2;
            continue;
        }
        let Some(h2) = hw(i + 2) else { break };
        if h1 >> 11 == 0b11110 && h2 >> 14 == 0b11 && (h2 >> 12) & 1 == 1 {
            // BL (T1) and B.W (T4): S:I1:I2:imm10:imm11:0
            out.targets.push(bl_target(pc, h1, h2));
        } else if h1 >> 11 == 0b11110 && h2 >> 14 == 0b10 && (h2 >> 12) & 1 == 1 {
            out.targets.push(bl_target(pc, h1, h2));
        } else if h1 >> 11 == 0b11110
            && h2 >> 14 == 0b10
            && (h2 >> 12) & 1 == 0
            && (h1 >> 7) & 0b111 != 0b111
        {
            // B<c>.W (T3): S:J2:J1:imm6:imm11:0
            let s = (h1 >> 10) & 1;
            let j1 = (h2 >> 13) & 1;
            let j2 = (h2 >> 11) & 1;
            let imm = s << 20 | j2 << 19 | j1 << 18 | (h1 & 0x3F) << 12 | (h2 & 0x7FF) << 1;
            out.targets
                .push(pc.wrapping_add(4).wrapping_add_signed(sext(imm, 21)));
        } else if (h1 & 0xFFF0 == 0xF8D0 || h1 & 0xFFF0 == 0xF850) && h2 >> 12 == 0xF {
            out.indirect = true; // LDR PC, [...]
        }
        i += 4;
    }
    out
}

fn bl_target(pc: u32, h1: u32, h2: u32) -> u32 {
    let s = (h1 >> 10) & 1;
    let i1 = !((h2 >> 13) ^ s) & 1;
    let i2 = !((h2 >> 11) ^ s) & 1;
    let imm = s << 24 | i1 << 23 | i2 << 22 | (h1 & 0x3FF) << 12 | (h2 & 0x7FF) << 1;
    pc.wrapping_add(4).wrapping_add_signed(sext(imm, 25))
}

/// The call graph of an image.
pub struct Graph {
    pub funcs: Vec<Func>,
    pub calls: Vec<Vec<usize>>,
    pub indirect: Vec<bool>,
    pub address_taken: Vec<bool>,
}

impl Graph {
    pub fn containing(&self, addr: u32) -> Option<usize> {
        let addr = addr & !1;
        self.funcs
            .iter()
            .position(|f| f.start <= addr && addr < f.end.max(f.start + 1))
    }

    /// A path from `root` to a panicking function, if there is one, not
    /// entering functions whose name holds a fragment of `stop`.
    pub fn panic_path(&self, root: usize, stop: &[&str]) -> Option<Vec<usize>> {
        let n = self.funcs.len();
        let mut parent = vec![usize::MAX; n];
        let mut seen = vec![false; n];
        let mut queue = VecDeque::from([root]);
        seen[root] = true;
        let taken: Vec<usize> = (0..n).filter(|&f| self.address_taken[f]).collect();
        while let Some(f) = queue.pop_front() {
            if is_panicking(&self.funcs[f].name) {
                let mut path = vec![f];
                let mut at = f;
                while parent[at] != usize::MAX {
                    at = parent[at];
                    path.push(at);
                }
                path.reverse();
                return Some(path);
            }
            let indirect = if self.indirect[f] { &taken[..] } else { &[] };
            for &g in self.calls[f].iter().chain(indirect) {
                if !seen[g] && !stop.iter().any(|s| self.funcs[g].name.contains(s)) {
                    seen[g] = true;
                    parent[g] = f;
                    queue.push_back(g);
                }
            }
        }
        None
    }
}

fn word_at(bytes: &[u8], at: usize) -> Option<u32> {
    Some(u32::from_le_bytes(bytes.get(at..at + 4)?.try_into().ok()?))
}

/// An image's code as the decoders need it: the bytes at an address, and
/// whether a halfword lies in a literal pool (from the `$d`/`$t` mapping
/// symbols: `$d` starts a pool, `$t` code again).
pub struct Code<'a> {
    img: &'a Image,
    maps: Vec<(u32, bool)>,
}

impl<'a> Code<'a> {
    pub fn new(img: &'a Image) -> Self {
        let mut maps: Vec<(u32, bool)> = img
            .symbols
            .iter()
            .filter(|s| s.3 == 0 && (s.0.starts_with("$d") || s.0.starts_with("$t")))
            .map(|s| (s.1 & !1, s.0.starts_with("$d")))
            .collect();
        maps.sort();
        Self { img, maps }
    }

    pub fn is_data(&self, a: u32) -> bool {
        match self.maps.partition_point(|m| m.0 <= a) {
            0 => false,
            k => self.maps[k - 1].1,
        }
    }

    pub fn bytes(&self, start: u32, len: u32) -> Option<&'a [u8]> {
        self.img.sections.iter().find_map(|(_, base, b)| {
            let off = start.checked_sub(*base)? as usize;
            b.get(off..off + len as usize)
        })
    }
}

pub fn graph(img: &Image) -> Graph {
    let mut funcs: Vec<Func> = img
        .symbols
        .iter()
        .filter(|s| s.3 == 2 && s.1 != 0)
        .map(|s| Func {
            name: s.0.clone(),
            start: s.1 & !1,
            end: (s.1 & !1) + s.2,
        })
        .collect();
    funcs.sort_by_key(|f| (f.start, std::cmp::Reverse(f.end)));
    funcs.dedup_by_key(|f| f.start);
    let code = Code::new(img);
    let is_data = |a: u32| code.is_data(a);
    let bytes_at = |start: u32, len: u32| code.bytes(start, len);
    let mut g = Graph {
        calls: vec![Vec::new(); funcs.len()],
        indirect: vec![false; funcs.len()],
        address_taken: vec![false; funcs.len()],
        funcs,
    };
    for f in 0..g.funcs.len() {
        let (start, end) = (g.funcs[f].start, g.funcs[f].end);
        let Some(code) = bytes_at(start, end - start) else {
            continue;
        };
        let br = decode(start, code, &is_data);
        g.indirect[f] = br.indirect;
        let mut calls: Vec<usize> = br
            .targets
            .iter()
            .filter(|&&t| t < start || t >= end)
            .filter_map(|&t| g.containing(t))
            .collect();
        calls.sort_unstable();
        calls.dedup();
        g.calls[f] = calls;
    }
    // Any word equal to a function's Thumb address, outside the vector
    // table, may be a function pointer.
    let starts: std::collections::HashMap<u32, usize> = g
        .funcs
        .iter()
        .enumerate()
        .map(|(i, f)| (f.start | 1, i))
        .collect();
    for (name, _, b) in &img.sections {
        if name == ".vector_table" {
            continue;
        }
        for at in (0..b.len()).step_by(4) {
            if let Some(f) = word_at(b, at).and_then(|w| starts.get(&w)) {
                g.address_taken[*f] = true;
            }
        }
    }
    g
}

/// (vector number, handler function) for every vector but the initial SP,
/// Reset (1) and HardFault (3).
pub fn handler_roots(img: &Image, g: &Graph) -> Result<Vec<(usize, usize)>, String> {
    let (_, _, vt) = img
        .sections
        .iter()
        .find(|s| s.0 == ".vector_table")
        .ok_or("no .vector_table section")?;
    let mut roots = Vec::new();
    for v in 2..vt.len() / 4 {
        if v == 3 {
            continue;
        }
        let Some(w) = word_at(vt, v * 4) else { break };
        if w == 0 {
            continue; // reserved vector
        }
        let f = g
            .containing(w)
            .ok_or_else(|| format!("vector {v} = {w:#010x} is in no function symbol"))?;
        if !roots.iter().any(|&(_, r)| r == f) {
            roots.push((v, f));
        }
    }
    Ok(roots)
}

/// Thread-mode functions held to the same rule as the handlers: the host
/// link's service (`zslide::link::station::Station::poll`, and
/// `poll_with_store` on a board whose parameter store saves), which takes
/// whatever bytes the host sends. Matched on the mangled name's path parts.
const THREAD_ROOTS: [[&str; 2]; 2] = [["7station", "4poll"], ["7station", "15poll_with_store"]];

/// Where the thread roots' check stops: the parameter store's save
/// (`<zslide::store::Store<F> as ParamStore>::save`, never inlined).
/// `sequential-storage` under it has `unwrap`s and index checks; it runs
/// only on a host's `SaveParams`, only while the loop is disarmed (the
/// amplifier off), and a panic there ends, like a power cut during the
/// save, in a reset of a disarmed machine whose store keeps the old block
/// or the new one (`cargo xtask flash-cut`). Reported in the summary.
const THREAD_STOPS: &[&str] = &["zslide..store..ParamStore$GT$4save"];

/// (0, function) for each [`THREAD_ROOTS`] function in the image.
fn thread_roots(g: &Graph) -> Vec<(usize, usize)> {
    (0..g.funcs.len())
        .filter(|&f| {
            THREAD_ROOTS
                .iter()
                .any(|parts| parts.iter().all(|p| g.funcs[f].name.contains(p)))
        })
        .map(|f| (0, f))
        .collect()
}

/// Checks one image; Ok(summary) or Err(the panic paths found).
/// `link`: the image serves the host link, so its `Station::poll` must be
/// there (and is checked); the centring image has none.
pub fn check(path: &Path, link: bool) -> Result<String, String> {
    let img = elf::image(path)?;
    let g = graph(&img);
    let mut roots = handler_roots(&img, &g)?;
    let thread = thread_roots(&g);
    if link && thread.is_empty() {
        return Err(format!(
            "{}: the host link's Station::poll (or poll_with_store) is not in the image as a function",
            path.display()
        ));
    }
    let handlers = roots.len();
    roots.extend(thread);
    let mut bad = Vec::new();
    for (i, &(v, r)) in roots.iter().enumerate() {
        let stop = if i < handlers { &[][..] } else { THREAD_STOPS };
        if let Some(path) = g.panic_path(r, stop) {
            let names: Vec<&str> = path.iter().map(|&f| g.funcs[f].name.as_str()).collect();
            bad.push(format!("vector {v}: {}", names.join("\n      -> ")));
        }
    }
    let present: Vec<&str> = g
        .funcs
        .iter()
        .filter(|f| is_panicking(&f.name))
        .map(|f| f.name.as_str())
        .collect();
    let names: Vec<&str> = roots
        .iter()
        .map(|&(_, r)| g.funcs[r].name.as_str())
        .collect();
    if bad.is_empty() {
        Ok(format!(
            "{}: no panic path from {} handlers ({}; the thread roots' check stops at {}); \
             panicking functions in the image \
             (reachable only from boot, thread mode or HardFault): {}",
            path.display(),
            roots.len(),
            names.join(", "),
            THREAD_STOPS.join(", "),
            if present.is_empty() {
                "none".to_string()
            } else {
                present.join(", ")
            }
        ))
    } else {
        Err(format!(
            "{}: panic path(s) reachable from interrupt handlers:\n  {}",
            path.display(),
            bad.join("\n  ")
        ))
    }
}

// ---------------------------------------------------------------- command

use crate::images::{build_board, build_qemu};
use crate::tools::{require, Tool};
use crate::{board_elf, centre_elf, qemu_elf, step};

pub fn run() -> crate::Result<u8> {
    require(&[Tool::Target, Tool::FlipLink])?;
    build_board()?;
    build_qemu()?;
    check_images()?;
    Ok(0)
}

/// Every image: no panic path from any interrupt handler (`nopanic.rs`).
pub fn check_images() -> crate::Result<()> {
    step("no panic path from interrupt handlers (every image)");
    let mut errors = Vec::new();
    for (elf, link) in [
        (board_elf(), true),
        (centre_elf(), false),
        (qemu_elf(), true),
    ] {
        match check(&elf, link) {
            Ok(summary) => eprintln!("{summary}"),
            Err(e) => errors.push(e),
        }
    }
    if errors.is_empty() {
        Ok(())
    } else {
        Err(errors.join("\n"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// BL encoding (T1) of a call from `pc` to `to`, as the assembler would.
    fn bl(pc: u32, to: u32) -> [u8; 4] {
        let off = to.wrapping_sub(pc + 4) as i32;
        let imm = (off as u32) >> 1;
        let s = (imm >> 23) & 1;
        let i1 = (imm >> 22) & 1;
        let i2 = (imm >> 21) & 1;
        let j1 = (!(i1 ^ s)) & 1;
        let j2 = (!(i2 ^ s)) & 1;
        let h1 = 0xF000 | s << 10 | ((imm >> 11) & 0x3FF);
        let h2 = 0xD000 | j1 << 13 | j2 << 11 | (imm & 0x7FF);
        let mut out = [0; 4];
        out[..2].copy_from_slice(&(h1 as u16).to_le_bytes());
        out[2..].copy_from_slice(&(h2 as u16).to_le_bytes());
        out
    }

    #[test]
    fn bl_decodes_known_encodings() {
        // From the NUCLEO image (llvm-objdump): at 0x800932e
        // `bl 0x8000836` is f7f7 fa82 (backward, S = 1).
        let code = [0xF7, 0xF7, 0x82, 0xFA];
        let br = decode(0x0800_932E, &code, &|_| false);
        assert_eq!(br.targets, vec![0x0800_0836]);
        // Forward: 0x8000896 `bl 0x800952e` is f008 fe4a.
        let code = [0x08, 0xF0, 0x4A, 0xFE];
        let br = decode(0x0800_0896, &code, &|_| false);
        assert_eq!(br.targets, vec![0x0800_952E]);
        assert_eq!(bl(0x0800_0896, 0x0800_952E), code);
    }

    #[test]
    fn literal_pools_and_returns_are_not_branches() {
        // A pool word that would decode as a BL, marked as data.
        let code = bl(0x100, 0x200);
        assert!(decode(0x100, &code, &|_| true).targets.is_empty());
        // BX LR is a return; BLX R3 is an indirect call.
        assert!(!decode(0, &[0x70, 0x47], &|_| false).indirect);
        assert!(decode(0, &[0x98, 0x47], &|_| false).indirect);
    }

    /// A synthetic image: a vector table whose IRQ handler `loop_tick`
    /// calls `helper`, which (in the injected case) calls
    /// `core::panicking::panic_bounds_check` - what an out-of-bounds index
    /// or a `panic!()` in the loop tick would link in.
    fn image(inject: bool) -> Image {
        let sym = |n: &str, a: u32, s: u32| (n.to_string(), a | 1, s, 2u8);
        let mut text = vec![0u8; 0x40];
        // nop (bf00) everywhere, bx lr at the end of each function.
        for i in (0..0x40).step_by(2) {
            text[i..i + 2].copy_from_slice(&[0x00, 0xBF]);
        }
        text[0..4].copy_from_slice(&bl(0x1000, 0x1010)); // loop_tick -> helper
        if inject {
            text[0x10..0x14].copy_from_slice(&bl(0x1010, 0x1020));
        }
        text[0x1E..0x20].copy_from_slice(&[0x70, 0x47]);
        let mut vt = vec![0u8; 17 * 4];
        vt[4..8].copy_from_slice(&(0x1031u32).to_le_bytes()); // Reset
        vt[16 * 4..].copy_from_slice(&(0x1001u32).to_le_bytes()); // IRQ0
        Image {
            symbols: vec![
                sym("loop_tick", 0x1000, 0x10),
                sym("helper", 0x1010, 0x10),
                sym("_ZN4core9panicking18panic_bounds_check17h0E", 0x1020, 0x10),
                sym("Reset", 0x1030, 0x10),
            ],
            sections: vec![
                (".vector_table".into(), 0, vt),
                (".text".into(), 0x1000, text),
            ],
        }
    }

    #[test]
    fn an_injected_panic_in_the_loop_tick_is_found() {
        for inject in [false, true] {
            let img = image(inject);
            let g = graph(&img);
            let roots = handler_roots(&img, &g).expect("roots");
            assert_eq!(roots.len(), 1);
            let path = g.panic_path(roots[0].1, &[]);
            if inject {
                let names: Vec<&str> = path
                    .expect("the injected panic is reachable")
                    .iter()
                    .map(|&f| g.funcs[f].name.as_str())
                    .collect();
                assert_eq!(names[..2], ["loop_tick", "helper"]);
                assert!(names[2].contains("panic_bounds_check"));
            } else {
                assert!(path.is_none());
            }
        }
    }

    #[test]
    fn an_indirect_call_may_reach_any_address_taken_function() {
        let mut img = image(false);
        // helper: blx r3 instead of a nop; the panicking function's address
        // stored in .rodata.
        img.sections[1].2[0x12..0x14].copy_from_slice(&[0x98, 0x47]);
        img.sections
            .push((".rodata".into(), 0x2000, 0x1021u32.to_le_bytes().to_vec()));
        let g = graph(&img);
        let roots = handler_roots(&img, &g).expect("roots");
        assert!(g.panic_path(roots[0].1, &[]).is_some());
    }
}
