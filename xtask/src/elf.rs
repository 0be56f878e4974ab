//! Just enough of ELF32 (little endian) to size an image and find symbols,
//! so that no binutils are needed.

use std::fs;
use std::path::Path;

const SHF_WRITE: u32 = 1;
const SHF_ALLOC: u32 = 2;
const SHT_SYMTAB: u32 = 2;
const SHT_NOBITS: u32 = 8;

/// Section sizes the way `size` (Berkeley format) groups them.
#[derive(Debug, Default, Clone, Copy)]
pub struct Sizes {
    /// Allocated, read-only: vector table, code, read-only data.
    pub text: u64,
    /// Allocated, writable, initialised: in flash and copied to RAM.
    pub data: u64,
    /// Allocated, writable, zeroed or uninitialised: RAM only.
    pub bss: u64,
}

impl Sizes {
    pub fn flash(&self) -> u64 {
        self.text + self.data
    }
    /// Static RAM (stack not included: it takes the rest).
    pub fn ram(&self) -> u64 {
        self.data + self.bss
    }
}

struct Section {
    name: u32,
    kind: u32,
    flags: u32,
    addr: u32,
    offset: u32,
    size: u32,
    link: u32,
}

fn u16_at(b: &[u8], at: usize) -> Option<u16> {
    Some(u16::from_le_bytes(b.get(at..at + 2)?.try_into().ok()?))
}
fn u32_at(b: &[u8], at: usize) -> Option<u32> {
    Some(u32::from_le_bytes(b.get(at..at + 4)?.try_into().ok()?))
}

fn sections(b: &[u8]) -> Option<Vec<Section>> {
    if b.get(0..4)? != b"\x7fELF" || *b.get(4)? != 1 || *b.get(5)? != 1 {
        return None; // not ELF32 little endian
    }
    let shoff = u32_at(b, 0x20)? as usize;
    let shentsize = u16_at(b, 0x2E)? as usize;
    let shnum = u16_at(b, 0x30)? as usize;
    (0..shnum)
        .map(|i| {
            let h = shoff + i * shentsize;
            Some(Section {
                name: u32_at(b, h)?,
                kind: u32_at(b, h + 4)?,
                flags: u32_at(b, h + 8)?,
                addr: u32_at(b, h + 12)?,
                offset: u32_at(b, h + 16)?,
                size: u32_at(b, h + 20)?,
                link: u32_at(b, h + 24)?,
            })
        })
        .collect()
}

fn read(path: &Path) -> Result<Vec<u8>, String> {
    fs::read(path).map_err(|e| format!("{}: {e}", path.display()))
}

pub fn sizes(path: &Path) -> Result<Sizes, String> {
    let b = read(path)?;
    let secs = sections(&b).ok_or_else(|| format!("{}: not an ELF32 LE file", path.display()))?;
    let _ = secs.first().map(|s| s.name);
    let mut s = Sizes::default();
    for sec in secs.iter().filter(|s| s.flags & SHF_ALLOC != 0) {
        let size = u64::from(sec.size);
        if sec.kind == SHT_NOBITS {
            s.bss += size;
        } else if sec.flags & SHF_WRITE != 0 {
            s.data += size;
        } else {
            s.text += size;
        }
    }
    Ok(s)
}

/// A function symbol: name, address (Thumb bit cleared), size in bytes.
#[derive(Debug, Clone)]
pub struct Symbol {
    pub name: String,
    pub addr: u32,
    pub size: u32,
}

/// The function symbols (STT_FUNC) of the image: [`image`]'s symbol table,
/// filtered, with the Thumb bit cleared.
pub fn functions(path: &Path) -> Result<Vec<Symbol>, String> {
    const STT_FUNC: u8 = 2;
    Ok(image(path)?
        .symbols
        .into_iter()
        .filter(|s| s.3 == STT_FUNC)
        .map(|(name, value, size, _)| Symbol {
            name,
            addr: value & !1,
            size,
        })
        .collect())
}

/// What the panic-path check needs of an image: every symbol with its kind,
/// and the bytes of the allocated, initialised sections at their addresses.
pub struct Image {
    /// (name, value, size, STT_* kind); the value keeps the Thumb bit.
    pub symbols: Vec<(String, u32, u32, u8)>,
    /// (section name, load address, bytes) of each allocated PROGBITS section.
    pub sections: Vec<(String, u32, Vec<u8>)>,
}

fn c_str(b: &[u8], at: usize) -> String {
    let Some(tail) = b.get(at..) else {
        return String::new();
    };
    let end = tail.iter().position(|&c| c == 0).unwrap_or(tail.len());
    String::from_utf8_lossy(&tail[..end]).into_owned()
}

pub fn image(path: &Path) -> Result<Image, String> {
    let b = read(path)?;
    let bad = || format!("{}: malformed ELF", path.display());
    let secs = sections(&b).ok_or_else(bad)?;
    let shstrndx = u16_at(&b, 0x32).ok_or_else(bad)? as usize;
    let shstr = secs.get(shstrndx).ok_or_else(bad)?;
    let mut sections = Vec::new();
    for s in secs
        .iter()
        .filter(|s| s.flags & SHF_ALLOC != 0 && s.kind != SHT_NOBITS && s.size > 0)
    {
        let bytes = b
            .get(s.offset as usize..(s.offset as usize + s.size as usize))
            .ok_or_else(bad)?;
        let name = c_str(&b, shstr.offset as usize + s.name as usize);
        sections.push((name, s.addr, bytes.to_vec()));
    }
    let symtab = secs
        .iter()
        .find(|s| s.kind == SHT_SYMTAB)
        .ok_or_else(|| format!("{}: no symbol table", path.display()))?;
    let strtab = secs.get(symtab.link as usize).ok_or_else(bad)?;
    let mut symbols = Vec::new();
    for i in 0..symtab.size as usize / 16 {
        let at = symtab.offset as usize + i * 16;
        let (Some(name), Some(value), Some(size), Some(&info)) = (
            u32_at(&b, at),
            u32_at(&b, at + 4),
            u32_at(&b, at + 8),
            b.get(at + 12),
        ) else {
            return Err(bad());
        };
        let name = c_str(&b, strtab.offset as usize + name as usize);
        symbols.push((name, value, size, info & 0xF));
    }
    Ok(Image { symbols, sections })
}
