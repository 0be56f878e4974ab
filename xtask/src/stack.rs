//! Worst-case stack depth of an image's entry points, from its machine
//! code: each function's frame is the sum of the stack pointer decrements
//! in its code (PUSH, PUSH.W/STMDB SP!, STR Rt,[SP,#-n]!, SUB SP,#n in its
//! three encodings, VPUSH), and an entry point's depth is its frame plus
//! the deepest of its callees along the call graph of `nopanic` (direct
//! branches, BL and tail-call B.W alike).
//!
//! Limits, all on the safe side: a function's decrements are summed over
//! all its paths (shrink-wrapped code that pushes on two exclusive paths
//! counts both); a tail call counts the callee on top of the caller's
//! frame, which it has already released; an indirect call may reach every
//! address-taken function (as in the panic check). What the analysis
//! refuses rather than bounds: a stack pointer moved by a register (an
//! `alloca`, none in this firmware) and recursion; both are reported
//! instead of a number. Not included: the exception frame the core pushes
//! on entry (8 words, or 26 with a lazily stacked FPU context, plus a word
//! of 8-byte alignment: 108 bytes), reported beside the depth.

use std::collections::HashMap;

use crate::elf::Image;
use crate::nopanic::{self, Code, Graph};

/// The core's worst exception frame: 26 words with the FPU context, plus
/// the alignment word.
pub const EXCEPTION_FRAME_BYTES: u32 = 108;

/// A function's own stack use.
#[derive(Debug, Default, PartialEq, Eq)]
pub struct Frame {
    pub bytes: u32,
    /// The stack pointer is set from a register other than to restore it
    /// (an unbounded allocation): no bound.
    pub dynamic: bool,
}

fn thumb_expand_imm(imm12: u32) -> u32 {
    if imm12 >> 10 == 0 {
        let b = imm12 & 0xFF;
        match (imm12 >> 8) & 3 {
            0 => b,
            1 => b << 16 | b,
            2 => b << 24 | b << 8,
            _ => b << 24 | b << 16 | b << 8 | b,
        }
    } else {
        (0x80 | (imm12 & 0x7F)).rotate_right(imm12 >> 7)
    }
}

/// The stack pointer decrements of Thumb-2 code at `addr`.
pub fn frame(addr: u32, code: &[u8], is_data: &dyn Fn(u32) -> bool) -> Frame {
    let mut f = Frame::default();
    let hw = |i: usize| -> Option<u32> {
        Some(u32::from(u16::from_le_bytes([
            *code.get(i)?,
            *code.get(i + 1)?,
        ])))
    };
    let mut i = 0usize;
    while let Some(h1) = hw(i) {
        if is_data(addr.wrapping_add(i as u32)) {
            i += 2;
            continue;
        }
        if !matches!(h1 >> 11, 0b11101..=0b11111) {
            if h1 & 0xFE00 == 0xB400 {
                // PUSH {regs[, lr]}
                f.bytes += 4 * ((h1 & 0xFF).count_ones() + ((h1 >> 8) & 1));
            } else if h1 & 0xFF80 == 0xB080 {
                // SUB SP, SP, #imm7·4
                f.bytes += (h1 & 0x7F) * 4;
            } else if h1 & 0xFF78 == 0x4468 && (h1 >> 7) & 1 == 1 && h1 & 7 == 5 {
                // ADD SP, Rm (T2 with Rdn = SP): moves SP by a register.
                f.dynamic = true;
            }
            i += 2;
            continue;
        }
        let Some(h2) = hw(i + 2) else { break };
        if h1 == 0xE92D {
            // PUSH.W {regs} (STMDB SP!)
            f.bytes += 4 * (h2 & 0xFFFF).count_ones();
        } else if h1 == 0xF84D && h2 & 0x0F00 == 0x0D00 {
            // STR Rt, [SP, #-imm8]! (PUSH of one register)
            f.bytes += h2 & 0xFF;
        } else if h1 & 0xFBEF == 0xF1AD && h2 & 0x8F00 == 0x0D00 {
            // SUB{S}.W SP, SP, #const
            let imm12 = ((h1 >> 10) & 1) << 11 | ((h2 >> 12) & 7) << 8 | (h2 & 0xFF);
            f.bytes += thumb_expand_imm(imm12);
        } else if h1 & 0xFBFF == 0xF2AD && h2 & 0x8F00 == 0x0D00 {
            // SUBW SP, SP, #imm12
            f.bytes += ((h1 >> 10) & 1) << 11 | ((h2 >> 12) & 7) << 8 | (h2 & 0xFF);
        } else if h1 == 0xED2D && matches!(h2 & 0x0F00, 0x0A00 | 0x0B00) {
            // VPUSH {s/d regs}: imm8 words
            f.bytes += (h2 & 0xFF) * 4;
        } else if h1 & 0xFFE0 == 0xEBA0 && h1 & 0xF == 0xD && (h2 >> 8) & 0xF == 0xD {
            // SUB.W SP, SP, Rm: an allocation by a register.
            f.dynamic = true;
        }
        i += 4;
    }
    f
}

/// An entry point's worst-case depth, or why there is no bound.
#[derive(Debug, PartialEq, Eq)]
pub enum Depth {
    Bytes(u32),
    Recursion(String),
    Dynamic(String),
}

/// Worst-case depths over the call graph, memoised per function.
pub struct Analysis<'a> {
    g: &'a Graph,
    frames: Vec<Frame>,
    memo: HashMap<usize, Depth>,
    on_path: Vec<bool>,
    taken: Vec<usize>,
}

impl<'a> Analysis<'a> {
    pub fn new(img: &Image, g: &'a Graph) -> Self {
        let code = Code::new(img);
        let frames = g
            .funcs
            .iter()
            .map(|f| {
                code.bytes(f.start, f.end - f.start)
                    .map(|b| frame(f.start, b, &|a| code.is_data(a)))
                    .unwrap_or_default()
            })
            .collect();
        Self {
            g,
            frames,
            memo: HashMap::new(),
            on_path: vec![false; g.funcs.len()],
            taken: (0..g.funcs.len()).filter(|&f| g.address_taken[f]).collect(),
        }
    }

    /// The worst-case stack depth of function `f` and everything it calls.
    pub fn depth(&mut self, f: usize) -> Depth {
        if let Some(d) = self.memo.get(&f) {
            return match d {
                Depth::Bytes(b) => Depth::Bytes(*b),
                Depth::Recursion(s) => Depth::Recursion(s.clone()),
                Depth::Dynamic(s) => Depth::Dynamic(s.clone()),
            };
        }
        let name = || self.g.funcs[f].name.clone();
        if self.on_path[f] {
            return Depth::Recursion(name());
        }
        if self.frames[f].dynamic {
            return Depth::Dynamic(name());
        }
        self.on_path[f] = true;
        let callees: Vec<usize> = if self.g.indirect[f] {
            self.g.calls[f].iter().chain(&self.taken).copied().collect()
        } else {
            self.g.calls[f].clone()
        };
        let mut deepest = Depth::Bytes(0);
        for c in callees {
            match (self.depth(c), &deepest) {
                (Depth::Bytes(b), Depth::Bytes(d)) if b > *d => deepest = Depth::Bytes(b),
                (Depth::Bytes(_), _) => {}
                (unbounded, _) => {
                    deepest = unbounded;
                    break;
                }
            }
        }
        self.on_path[f] = false;
        let d = match deepest {
            Depth::Bytes(b) => Depth::Bytes(b + self.frames[f].bytes),
            other => other,
        };
        let stored = match &d {
            Depth::Bytes(b) => Depth::Bytes(*b),
            Depth::Recursion(s) => Depth::Recursion(s.clone()),
            Depth::Dynamic(s) => Depth::Dynamic(s.clone()),
        };
        self.memo.insert(f, stored);
        d
    }
}

/// The depths of the named functions (report name, symbol pattern as
/// `isr-cost` matches it).
pub fn depths(img: &Image, names: &[(String, &str)]) -> Vec<(String, Depth)> {
    let g = nopanic::graph(img);
    let mut a = Analysis::new(img, &g);
    let mut out = Vec::new();
    for (report, pattern) in names {
        if let Some(f) = g
            .funcs
            .iter()
            .position(|f| f.name == *pattern || (pattern.len() > 8 && f.name.contains(pattern)))
        {
            out.push((report.clone(), a.depth(f)));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn code(halfwords: &[u16]) -> Vec<u8> {
        halfwords.iter().flat_map(|h| h.to_le_bytes()).collect()
    }

    /// Prologues as the compiler emits them (encodings from the QEMU
    /// image's disassembly): `push {r4, r5, r6, r7, lr}` (20 bytes),
    /// `push.w {r8, r9, r10, r11}` (16), `sub sp, #260` (260),
    /// `sub.w sp, sp, #1024` (1024), `subw sp, sp, #1000` (1000),
    /// `vpush {d8, d9}` (16), `str r4, [sp, #-8]!` (8).
    #[test]
    fn prologue_decrements_are_summed() {
        let cases: [(&[u16], u32); 7] = [
            (&[0xB5F0], 20),
            (&[0xE92D, 0x0F00], 16),
            (&[0xB0C1], 260),
            (&[0xF5AD, 0x6D80], 1024),
            (&[0xF2AD, 0x3DE8], 1000),
            (&[0xED2D, 0x8B04], 16),
            (&[0xF84D, 0x4D08], 8),
        ];
        for (hw, bytes) in cases {
            let f = frame(0, &code(hw), &|_| false);
            assert_eq!(
                f,
                Frame {
                    bytes,
                    dynamic: false
                },
                "{hw:x?}"
            );
        }
        // A whole prologue, a pool word that would decode as a push, and
        // the epilogue's `add sp` / `pop` (not counted).
        let all = code(&[0xB5F0, 0xE92D, 0x0F00, 0xB0C1, 0xB5F0, 0xB041, 0xBDF0]);
        let f = frame(0x100, &all, &|a| a == 0x108);
        assert_eq!(f.bytes, 20 + 16 + 260);
        // `sub.w sp, sp, r3` allocates by a register.
        assert!(frame(0, &code(&[0xEBAD, 0x0D03]), &|_| false).dynamic);
    }

    #[test]
    fn thumb_immediates_expand() {
        assert_eq!(thumb_expand_imm(0x0FF), 0xFF);
        assert_eq!(thumb_expand_imm(0x1AB), 0x00AB_00AB);
        assert_eq!(thumb_expand_imm(0x2AB), 0xAB00_AB00);
        assert_eq!(thumb_expand_imm(0x3AB), 0xABAB_ABAB);
        // 1024 = 0x80 ror 29: rotation 0b11101 → imm12 = 0b1110_1000_0000.
        assert_eq!(thumb_expand_imm(0xE80), 1024);
    }
}
