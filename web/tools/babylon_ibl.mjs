// Loads a .glb with Babylon.js in headless Chromium and probes its EXT_lights_image_based environment.
//
//   node web/tools/babylon_ibl.mjs JOB.json
//
// JOB.json: {"glb": file, "chromium": executable, "work": folder for the page and the profile,
//   "samples": [{"dirs": [[x, y, z], ...] glTF world directions, "lod": mip}, ...],
//   "mirrors": [{"dirs": [[x, y, z], ...], "roughness": r}, ...] (optional)}
// Prints a JSON summary: the texture's figures and SH (babylon_ibl_page.js `load`), the samples'
// RGB, the mirror's pixels, the console and every request that was not file:, data: or blob:.
// esbuild, puppeteer-core and Babylon.js come from build/node (scripts/setup_node.sh).
import fs from 'node:fs';
import path from 'node:path';
import { fileURLToPath, pathToFileURL } from 'node:url';

import { modules, require, withPage } from './chromium.mjs';

const here = path.dirname(fileURLToPath(import.meta.url));
const esbuild = require('esbuild');

const job = JSON.parse(fs.readFileSync(process.argv[2], 'utf8'));
const bundle = await esbuild.build({
  entryPoints: [path.join(here, 'babylon_ibl_page.js')],
  bundle: true,
  format: 'iife',
  write: false,
  target: 'es2020',
  nodePaths: [modules],
  logLevel: 'silent',
});
const script = bundle.outputFiles[0].text.replace(/<\/script/gi, '<\\/script');
const html = path.join(job.work, 'babylon_ibl.html');
fs.writeFileSync(html, `<!doctype html><html><body><script>${script}</script></body></html>`);

const summary = { console: [], requests: [], samples: [] };
await withPage(job.chromium, job.work, summary, async (page) => {
  await page.goto(pathToFileURL(html).href, { waitUntil: 'load' });
  const data = fs.readFileSync(job.glb).toString('base64');
  summary.texture = await page.evaluate((b64) => window.babylonProbe.load(b64), data);
  for (const probe of job.samples || []) {
    summary.samples.push(await page.evaluate((d, l) => window.babylonProbe.sample(d, l), probe.dirs, probe.lod));
  }
  summary.mirrors = [];
  for (const probe of job.mirrors || []) {
    summary.mirrors.push(await page.evaluate((d, r) => window.babylonProbe.mirror(d, r), probe.dirs, probe.roughness));
  }
});
console.log(JSON.stringify(summary));
