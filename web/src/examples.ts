// Examples: one drawn here (always available, used by the tests), and the project's
// examples/ scenes bundled at build time into examples/index.json.

import { blobToDataUri } from './images';
import { emptyScene, type SceneDoc } from './scene';

export interface ExampleEntry {
  name: string;
  title: string;
  /** URL of the scene JSON (images inlined), or null for the built-in one. */
  url: string | null;
}

export const BUILTIN: ExampleEntry = { name: 'grid', title: 'Grid with a cut (built in)', url: null };

/** A 512×512 test picture: coloured tiles and rings, so motion is easy to see. */
async function gridPicture(size: number): Promise<string> {
  const c = new OffscreenCanvas(size, size);
  const ctx = c.getContext('2d')!;
  const g = ctx.createLinearGradient(0, 0, size, size);
  g.addColorStop(0, '#f7e7c6');
  g.addColorStop(1, '#c9e3f2');
  ctx.fillStyle = g;
  ctx.fillRect(0, 0, size, size);
  const n = 8;
  const step = size / n;
  for (let j = 0; j < n; j++) {
    for (let i = 0; i < n; i++) {
      const hue = (i * 37 + j * 71) % 360;
      ctx.fillStyle = `hsl(${hue} 70% ${(i + j) % 2 ? 45 : 65}%)`;
      ctx.fillRect(i * step + step * 0.15, j * step + step * 0.15, step * 0.7, step * 0.7);
    }
  }
  ctx.strokeStyle = '#222';
  ctx.lineWidth = 3;
  for (let r = step; r < size * 0.7; r += step) {
    ctx.beginPath();
    ctx.arc(size / 2, size / 2, r, 0, Math.PI * 2);
    ctx.stroke();
  }
  ctx.fillStyle = '#111';
  ctx.font = `bold ${Math.round(size / 8)}px sans-serif`;
  ctx.textAlign = 'center';
  ctx.textBaseline = 'middle';
  ctx.fillText('inkwarp', size / 2, size / 2);
  return blobToDataUri(await c.convertToBlob({ type: 'image/png' }));
}

/** The built-in example: the picture pinned at its corners, with a vertical cut. */
export async function builtinScene(size = 512): Promise<SceneDoc> {
  const doc = emptyScene(size, size);
  doc.layers.push({ name: 'picture', image: await gridPicture(size) });
  const m = Math.round(size / 32);
  const far = size - 1 - m;
  doc.features.push(
    { id: 'pin1', kind: 'point', rest: [[m, m]] },
    { id: 'pin2', kind: 'point', rest: [[far, m]] },
    { id: 'pin3', kind: 'point', rest: [[m, far]] },
    { id: 'pin4', kind: 'point', rest: [[far, far]] },
    {
      id: 'slit',
      kind: 'cut',
      rest: [
        [Math.round(size * 0.6), Math.round(size * 0.2)],
        [Math.round(size * 0.6), Math.round(size * 0.8)],
      ],
    },
  );
  return doc;
}

/** The examples bundled with this build (the built-in one first). */
export async function listExamples(): Promise<ExampleEntry[]> {
  const list = [BUILTIN];
  try {
    const resp = await fetch('examples/index.json');
    if (resp.ok) {
      const entries = (await resp.json()) as { name: string; title: string; file: string }[];
      for (const e of entries) list.push({ name: e.name, title: e.title, url: `examples/${e.file}` });
    }
  } catch {
    // No bundled examples in this build.
  }
  return list;
}
