// Runs web/tools/bench_page.js (bundled by esbuild) in headless Chromium and prints its figures as JSON (benchmarks/bench_web.py).
//
//   node web/tools/bench_headless.mjs JOB.json     JOB: {"chromium", "glb", "out", "triangles", "rounds", "lights", "order"}
import fs from 'node:fs';
import path from 'node:path';
import { fileURLToPath, pathToFileURL } from 'node:url';

import { modules, require, withPage } from './chromium.mjs';

const here = path.dirname(fileURLToPath(import.meta.url));
const job = JSON.parse(fs.readFileSync(process.argv[2], 'utf8'));
const bundle = await require('esbuild').build({
  entryPoints: [path.join(here, 'bench_page.js')],
  bundle: true,
  format: 'iife',
  minify: true,
  write: false,
  target: 'es2020',
  nodePaths: [modules],
  logLevel: 'warning',
});
const html = `${job.out}_bench.html`;
const script = bundle.outputFiles[0].text.replace(/<\/(script)/gi, '<\\/$1');
fs.writeFileSync(html, `<!doctype html><html><body style="margin:0"><script>${script}</script></body></html>`);
const summary = { console: [], requests: [] };
const started = Date.now();
await withPage(job.chromium, path.dirname(job.out), summary, async (page) => {
  await page.setViewport({ width: 800, height: 600 });
  await page.goto(pathToFileURL(html).href, { waitUntil: 'load' });
  const data = fs.readFileSync(job.glb).toString('base64');
  const step = (what) => console.error(`bench_headless: ${what} (${((Date.now() - started) / 1000).toFixed(0)} s)`);
  summary.load = await page.evaluate((d) => window.prtBench.loadFile(d), data);
  step('file loaded');
  summary.setup = await page.evaluate(
    (n, l, o) => window.prtBench.setup(n, l, o),
    job.triangles,
    Boolean(job.lights),
    job.order || 8,
  );
  step('scene set up');
  summary.times = {};
  for (let round = 0; round < job.rounds; round++) {
    const times = await page.evaluate(() => window.prtBench.frames(1));
    for (const [name, values] of Object.entries(times)) (summary.times[name] ||= []).push(...values);
    step(
      `round ${round + 1}: ${Object.entries(times)
        .map(([n, v]) => `${n} ${v[0].toFixed(0)} ms`)
        .join(', ')}`,
    );
  }
});
console.log(JSON.stringify(summary));
