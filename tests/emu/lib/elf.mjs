// The little of ELF32 (little-endian, ARM) the harness needs: the loadable segments at their
// load addresses (flash), and symbol addresses (_SEGGER_RTT). Layout from the System V ABI,
// "ELF Header", "Program Header" and "Symbol Table" (Tool Interface Standard ELF 1.2).

const PT_LOAD = 1;
const SHT_SYMTAB = 2;

export function readElf(bytes) {
  const view = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
  const magic = view.getUint32(0, false);
  if (magic !== 0x7f454c46) throw new Error('not an ELF file');
  if (bytes[4] !== 1 || bytes[5] !== 1) throw new Error('not a 32-bit little-endian ELF');
  const u16 = (o) => view.getUint16(o, true);
  const u32 = (o) => view.getUint32(o, true);

  const segments = [];
  const phoff = u32(0x1c);
  for (let i = 0; i < u16(0x2c); i++) {
    const ph = phoff + i * u16(0x2a);
    if (u32(ph) !== PT_LOAD) continue;
    const offset = u32(ph + 4);
    const filesz = u32(ph + 16);
    // p_paddr: where the bytes are stored (flash), even for .data that runs from RAM.
    segments.push({ address: u32(ph + 12), data: bytes.subarray(offset, offset + filesz) });
  }

  const symbols = new Map();
  const shoff = u32(0x20);
  const shentsize = u16(0x2e);
  const section = (i) => {
    const sh = shoff + i * shentsize;
    return { type: u32(sh + 4), offset: u32(sh + 16), size: u32(sh + 20), link: u32(sh + 24) };
  };
  for (let i = 0; i < u16(0x30); i++) {
    const symtab = section(i);
    if (symtab.type !== SHT_SYMTAB) continue;
    const strtab = section(symtab.link);
    for (let s = symtab.offset; s < symtab.offset + symtab.size; s += 16) {
      const nameStart = strtab.offset + u32(s);
      let nameEnd = nameStart;
      while (bytes[nameEnd] !== 0) nameEnd++;
      const name = new TextDecoder().decode(bytes.subarray(nameStart, nameEnd));
      if (name) symbols.set(name, u32(s + 4));
    }
  }
  return { segments, symbols };
}
