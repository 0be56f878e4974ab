//! The image as a probe flashes it: every loadable segment at its load
//! (physical) address, and the symbols the emulator needs.

use object::{Object, ObjectSegment, ObjectSymbol};

pub struct Image {
    /// (load address, bytes) of every segment with file contents.
    pub segments: Vec<(u32, Vec<u8>)>,
    /// `_SEGGER_RTT`, the RTT control block a probe looks for.
    pub rtt: Option<u32>,
}

pub fn load(bytes: &[u8]) -> Result<Image, String> {
    let file = object::File::parse(bytes).map_err(|e| format!("not an ELF: {e}"))?;
    let elf = match &file {
        object::File::Elf32(f) => f,
        _ => return Err("not a 32-bit ELF".into()),
    };
    let mut segments = Vec::new();
    for seg in elf.segments() {
        let data = seg.data().map_err(|e| e.to_string())?;
        if data.is_empty() {
            continue;
        }
        let paddr = seg
            .elf_program_header()
            .p_paddr
            .get(object::Endianness::Little);
        segments.push((paddr, data.to_vec()));
    }
    let rtt = file
        .symbols()
        .find(|s| s.name() == Ok("_SEGGER_RTT"))
        .map(|s| s.address() as u32);
    Ok(Image { segments, rtt })
}
