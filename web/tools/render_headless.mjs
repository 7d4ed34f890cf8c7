// Renders a PRT .glb in the built viewer in headless Chromium: linear float images and screenshots.
//
//   node web/tools/render_headless.mjs JOB.json
//
// JOB.json: {"html": viewer page, "glb": file (omit it for a page with the .glb embedded),
//   "chromium": executable, "width": W, "height": H,
//   "turns": [[9 numbers, row-major 3x3 lighting rotation, glTF frame], ...],
//   "out": prefix, "screenshots": true, "drag": [dx, dy] (optional: a left-button mouse drag over
//   the page after the turns, from the identity turn; the viewer's turn after it is in the summary)}
// Writes PREFIX_<i>.f32 (W x H x 4 float32, linear radiance, top row first) per turn, and
// PREFIX_<i>.png screenshots of the page as a user sees it; prints a JSON summary (WebGL renderer,
// the viewer's info or its error message, every request that was not file:, data: or blob:, timings).
// puppeteer-core comes from build/node (scripts/setup_node.sh).
import fs from 'node:fs';
import path from 'node:path';
import { pathToFileURL } from 'node:url';

import { withPage } from './chromium.mjs';

const job = JSON.parse(fs.readFileSync(process.argv[2], 'utf8'));
const started = Date.now();
const summary = { images: [], screenshots: [], console: [], requests: [] };
await withPage(job.chromium, path.dirname(job.out), summary, async (page) => {
  await page.setViewport({ width: job.width, height: job.height });
  await page.goto(pathToFileURL(job.html).href, { waitUntil: 'load' });
  summary.renderer = await page.evaluate(() => {
    const gl = document.createElement('canvas').getContext('webgl2');
    if (!gl) return null;
    const ext = gl.getExtension('WEBGL_debug_renderer_info');
    return ext ? gl.getParameter(ext.UNMASKED_RENDERER_WEBGL) : gl.getParameter(gl.RENDERER);
  });
  if (!summary.renderer) throw new Error('no WebGL2 in this Chromium');
  const load = job.glb ? (text) => window.prtViewer.loadBase64(text, 'scene.glb') : () => window.prtViewer.ready;
  const data = job.glb ? fs.readFileSync(job.glb).toString('base64') : null;
  try {
    summary.info = await page.evaluate(load, data);
  } catch {
    summary.error = await page.evaluate(() => document.getElementById('message').textContent);
  }
  summary.loaded = (Date.now() - started) / 1000;
  for (const [i, turn] of (summary.error ? [] : job.turns).entries()) {
    const t0 = Date.now();
    const b64 = await page.evaluate(
      (m, w, h) => {
        window.prtViewer.setTurn(m);
        return window.prtViewer.renderLinear(w, h);
      },
      turn,
      job.width,
      job.height,
    );
    const file = `${job.out}_${i}.f32`;
    fs.writeFileSync(file, Buffer.from(b64, 'base64'));
    summary.images.push({ file, seconds: (Date.now() - t0) / 1000 });
    if (job.screenshots) {
      await page.evaluate(() => new Promise((resolve) => requestAnimationFrame(() => requestAnimationFrame(resolve))));
      const shot = `${job.out}_${i}.png`;
      await page.screenshot({ path: shot });
      summary.screenshots.push(shot);
    }
  }
  if (job.drag && !summary.error) {
    await page.evaluate(() => window.prtViewer.setTurn([1, 0, 0, 0, 1, 0, 0, 0, 1]));
    const [x, y] = [Math.round(job.width / 2), Math.round(job.height / 2)];
    await page.mouse.move(x, y);
    await page.mouse.down();
    for (let step = 1; step <= 10; step++) {
      await page.mouse.move(x + (job.drag[0] * step) / 10, y + (job.drag[1] * step) / 10);
    }
    await page.mouse.up();
    summary.dragTurn = await page.evaluate(() => window.prtViewer.turn());
    if (job.screenshots) {
      await page.evaluate(() => new Promise((resolve) => requestAnimationFrame(() => requestAnimationFrame(resolve))));
      summary.screenshots.push(`${job.out}_drag.png`);
      await page.screenshot({ path: `${job.out}_drag.png` });
    }
  }
});
summary.seconds = (Date.now() - started) / 1000;
console.log(JSON.stringify(summary));
