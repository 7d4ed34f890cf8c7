// Runs web/tools/plugin_page.js (bundled by esbuild) in headless Chromium: files loaded by the plugin, renders, console, for the tests.
//
//   node web/tools/plugin_headless.mjs JOB.json
//
// JOB.json: {"chromium": executable, "out": prefix, "files": [{"name", "glb", "plugin": true, "options"}],
//   "renders": [{options of pluginTest.render}], "release": [names]}. Writes PREFIX_<i>.bin per
// render (float32 or uint8 RGBA, top row first) and prints a JSON summary: per file what the
// loader made of it and the console messages its load printed, per render its file, the
// renderer's memory counts before anything was loaded and after each released file, and every
// request made.
import fs from 'node:fs';
import path from 'node:path';
import { fileURLToPath, pathToFileURL } from 'node:url';

import { modules, require, withPage } from './chromium.mjs';

const here = path.dirname(fileURLToPath(import.meta.url));
const job = JSON.parse(fs.readFileSync(process.argv[2], 'utf8'));
const esbuild = require('esbuild');
const bundle = await esbuild.build({
  entryPoints: [path.join(here, 'plugin_page.js')],
  bundle: true,
  format: 'iife',
  write: false,
  target: 'es2020',
  nodePaths: [modules],
  logLevel: 'warning',
});
const html = `${job.out}_page.html`;
fs.writeFileSync(
  html,
  `<!doctype html><html><body><script>${bundle.outputFiles[0].text.replace(/<\/(script)/gi, '<\\/$1')}</script></body></html>`,
);
const summary = { files: {}, renders: [], console: [], requests: [] };
await withPage(job.chromium, path.dirname(job.out), summary, async (page) => {
  await page.goto(pathToFileURL(html).href, { waitUntil: 'load' });
  summary.memory = await page.evaluate(() => window.pluginTest.memory());
  for (const file of job.files) {
    const before = summary.console.length;
    const data = fs.readFileSync(file.glb).toString('base64');
    try {
      summary.files[file.name] = await page.evaluate(
        (n, d, p, o) => window.pluginTest.load(n, d, p, o),
        file.name,
        data,
        file.plugin !== false,
        file.options || {},
      );
    } catch (error) {
      summary.files[file.name] = { error: String(error.message || error) };
    }
    summary.files[file.name].console = summary.console.slice(before);
  }
  for (const [i, options] of job.renders.entries()) {
    const b64 = await page.evaluate((o) => window.pluginTest.render(o), options);
    const file = `${job.out}_${i}.bin`;
    fs.writeFileSync(file, Buffer.from(b64, 'base64'));
    summary.renders.push({ file });
  }
  summary.released = {};
  for (const name of job.release || [])
    summary.released[name] = await page.evaluate((n) => window.pluginTest.release(n), name);
});
console.log(JSON.stringify(summary));
