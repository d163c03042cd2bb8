// Where `tests/emu/run` puts what the harness needs (all overridable).
import path from 'node:path';
import { fileURLToPath } from 'node:url';

export const repoRoot = path.resolve(path.dirname(fileURLToPath(import.meta.url)), '../../..');
const env = process.env;
export const defaults = {
  elf:
    env.IMUNOISE_EMU_ELF ??
    path.join(repoRoot, 'target/emu/imunoise-board'),
  imunoise: env.IMUNOISE_BIN ?? path.join(repoRoot, 'target/debug/imunoise'),
  defmtPrint: env.DEFMT_PRINT ?? 'defmt-print',
};
