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
import { createRequire } from 'node:module';
import { fileURLToPath, pathToFileURL } from 'node:url';

const here = path.dirname(fileURLToPath(import.meta.url));
const modules = process.env.PRT_NODE_MODULES || path.join(here, '..', '..', 'build', 'node', 'node_modules');
const require = createRequire(path.join(modules, 'index.js'));
const esbuild = require('esbuild');
const puppeteer = require('puppeteer-core');

// render_headless.mjs's flags (software WebGL2: ANGLE on SwiftShader); that script runs on import.
const CHROMIUM_FLAGS = [
  '--headless=new',
  '--no-sandbox',
  '--use-angle=swiftshader',
  '--enable-unsafe-swiftshader',
  '--ignore-gpu-blocklist',
  '--disable-background-networking',
  '--disable-component-update',
  '--disable-sync',
  '--disable-quic',
  '--no-first-run',
  '--allow-file-access-from-files',
];

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

const userData = fs.mkdtempSync(path.join(job.work, 'chromium-profile-'));
const browser = await puppeteer.launch({
  executablePath: job.chromium,
  args: [...CHROMIUM_FLAGS, `--user-data-dir=${userData}`],
  headless: true,
  protocolTimeout: 600000,
  timeout: 180000,
});
const summary = { console: [], requests: [], samples: [] };
try {
  const page = await browser.newPage();
  page.on('console', (msg) => summary.console.push(`${msg.type()}: ${msg.text()}`));
  page.on('pageerror', (error) => summary.console.push(`pageerror: ${error.message}`));
  page.on('request', (request) => {
    if (!/^(file|data|blob):/.test(request.url())) summary.requests.push(request.url());
  });
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
} finally {
  await browser.close();
  fs.rmSync(userData, { recursive: true, force: true });
}
console.log(JSON.stringify(summary));
