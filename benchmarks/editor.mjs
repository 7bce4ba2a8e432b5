// The editor in headless Chromium (Debian's, software GPU), served by `inkwarp edit`:
//
//   node benchmarks/editor.mjs fold-order SCENE [TIME] [ROUNDS]
//       full frames with the fold order's depth test on and off (`orderFolds`), in
//       alternating rounds of one page: the median ratio on / off, multisampled and plain.
//   node benchmarks/editor.mjs layer-move SCENE
//       a Move drag of 40 pointer moves over the scene's first layer: the drag's time, the
//       settle after it, and how many grid builds the workers were asked for.
//
// Run from the repository root after `make editor`; playwright-core comes from web/.
import { spawn } from 'node:child_process';
import { createRequire } from 'node:module';
import { resolve } from 'node:path';

const repo = resolve(new URL('..', import.meta.url).pathname);
const { chromium } = createRequire(resolve(repo, 'web/package.json'))('playwright-core');
const [what, scene, ...rest] = process.argv.slice(2);
if (!['fold-order', 'layer-move'].includes(what) || !scene) {
  console.error('usage: node benchmarks/editor.mjs fold-order|layer-move SCENE [TIME] [ROUNDS]');
  process.exit(2);
}
const median = (a) => [...a].sort((x, y) => x - y)[Math.floor(a.length / 2)];

const server = spawn(resolve(repo, '.venv/bin/inkwarp'), ['edit', scene, '--no-browser', '--port', '0'], { stdio: ['ignore', 'pipe', 'ignore'] });
const url = await new Promise((ok) => {
  let out = '';
  server.stdout.on('data', (d) => {
    out += d;
    const m = out.match(/http:\/\/127\.0\.0\.1:\d+\/\S*/);
    if (m) ok(m[0]);
  });
});
const browser = await chromium.launch({ executablePath: '/usr/bin/chromium', args: ['--headless', '--no-sandbox', '--disable-gpu'] });
try {
  const page = await (await browser.newContext({ viewport: { width: 1400, height: 900 }, deviceScaleFactor: 1 })).newPage();
  await page.goto(url);
  await page.waitForSelector('body[data-ready]');
  const settle = async () => {
    await page.evaluate(() => window.inkwarp.app.idle());
    await page.waitForTimeout(1000);
    await page.evaluate(() => window.inkwarp.app.idle());
  };
  if (what === 'fold-order') {
    const [time = 0.5, rounds = 8] = rest.map(Number);
    await page.evaluate((t) => window.inkwarp.store.setView({ mode: 'pose', time: t }), time);
    await settle();
    const times = await page.evaluate(async (rounds) => {
      const { app } = window.inkwarp;
      const once = async (on, antialias) => {
        app.gl.orderFolds = on;
        const t = performance.now();
        app.draw(false, antialias);
        await app.gl.finished();
        return performance.now() - t;
      };
      const out = {};
      for (const antialias of [true, false]) {
        const rows = (out[antialias ? 'multisampled' : 'plain'] = []);
        await once(true, antialias);
        await once(false, antialias);
        for (let r = 0; r < rounds; r++) {
          const t = {};
          for (const on of r % 2 ? [false, true] : [true, false]) t[on] = await once(on, antialias);
          rows.push({ on: t.true, off: t.false });
        }
      }
      app.gl.orderFolds = true;
      return out;
    }, rounds);
    console.log('| full frame | on / off, median | on, ms | off, ms |\n|---|---|---|---|');
    for (const [kind, rows] of Object.entries(times)) {
      console.log(`| ${kind} | ${median(rows.map((r) => r.on / r.off)).toFixed(3)} | ${median(rows.map((r) => r.on)).toFixed(0)} | ${median(rows.map((r) => r.off)).toFixed(0)} |`);
    }
  } else {
    await settle();
    await page.evaluate(() => {
      const { app } = window.inkwarp;
      window.gridBuilds = 0;
      for (const c of app.clients) {
        const own = c.setGrid.bind(c);
        c.setGrid = (...a) => { window.gridBuilds++; return own(...a); };
      }
    });
    await page.click('#layer-move');
    const box = await page.locator('canvas').first().boundingBox();
    const [x, y] = [box.x + box.width / 2, box.y + box.height / 2];
    await page.mouse.move(x, y);
    await page.mouse.down();
    const t0 = Date.now();
    for (let i = 1; i <= 40; i++) {
      await page.mouse.move(x + 3 * i, y + 2 * i);
      await page.waitForTimeout(16);
    }
    await page.mouse.up();
    const t1 = Date.now();
    await page.evaluate(() => window.inkwarp.app.idle());
    const builds = await page.evaluate(() => window.gridBuilds);
    console.log(`drag of 40 moves ${t1 - t0} ms, settle ${Date.now() - t1} ms, ${builds} grid builds`);
  }
} finally {
  await browser.close();
  server.kill();
}
