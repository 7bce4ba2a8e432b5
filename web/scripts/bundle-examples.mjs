// Copies the project's example scenes into the editor build with their images inlined as
// data: URIs, so each example opens as one file: public/examples/<name>.json + index.json.

import { existsSync, mkdirSync, readdirSync, readFileSync, rmSync, statSync, writeFileSync } from 'node:fs';
import { dirname, extname, join, resolve } from 'node:path';
import { fileURLToPath } from 'node:url';

const here = dirname(fileURLToPath(import.meta.url));
const root = resolve(here, '../..');
const src = process.env.INKWARP_EXAMPLES_DIR ? resolve(process.env.INKWARP_EXAMPLES_DIR) : join(root, 'examples');
const out = resolve(here, '../public/examples');
const MIME = { '.png': 'image/png', '.jpg': 'image/jpeg', '.jpeg': 'image/jpeg' };

rmSync(out, { recursive: true, force: true });
mkdirSync(out, { recursive: true });
const index = [];
if (existsSync(src)) {
  for (const name of readdirSync(src).sort()) {
    const dir = join(src, name);
    if (!statSync(dir).isDirectory()) continue;
    for (const file of readdirSync(dir).sort()) {
      if (extname(file) !== '.json') continue;
      let doc;
      try {
        doc = JSON.parse(readFileSync(join(dir, file), 'utf8'));
      } catch {
        continue;
      }
      if (doc?.inkwarp !== 1 || !Array.isArray(doc.layers)) continue;
      const inline = (ref) => {
        if (typeof ref !== 'string' || ref.startsWith('data:')) return ref;
        const path = join(dir, ref);
        const mime = MIME[extname(path).toLowerCase()];
        if (!mime || !existsSync(path)) return ref;
        return `data:${mime};base64,${readFileSync(path).toString('base64')}`;
      };
      for (const layer of doc.layers) for (const k of ['image', 'alpha', 'continuity']) if (layer[k]) layer[k] = inline(layer[k]);
      const stem = file.replace(/\.json$/, '');
      const id = stem === 'scene' ? name : `${name}-${stem}`;
      writeFileSync(join(out, `${id}.json`), JSON.stringify(doc));
      index.push({ name: id, title: stem === 'scene' ? name : `${name} (${stem})`, file: `${id}.json` });
    }
  }
}
writeFileSync(join(out, 'index.json'), JSON.stringify(index, null, 1));
console.log(`bundled ${index.length} example scene(s): ${index.map((e) => e.name).join(', ') || 'none'}`);
