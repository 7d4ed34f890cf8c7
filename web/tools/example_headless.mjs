// Runs web/README.md's example as a three.js user would: its code bundled into a page served over HTTP with scene.glb beside it, in headless Chromium.
//
//   node web/tools/example_headless.mjs JOB.json     JOB: {"chromium", "dir" (holds scene.glb), "width", "height"}
//
// The README's js block (after its <!-- prettier-ignore -->) is bundled by esbuild with
// 'prt-lighting-three' aliased to web/src/index.js, written to DIR/index.html and served from DIR
// on 127.0.0.1; the page's WebGL draw calls are counted, and once a few frames after the first
// draw are done, DIR/example.png is a screenshot. Prints a JSON summary: console, requests served,
// draw calls.
import fs from 'node:fs';
import http from 'node:http';
import path from 'node:path';
import { fileURLToPath } from 'node:url';

import { modules, require, withPage } from './chromium.mjs';

const here = path.dirname(fileURLToPath(import.meta.url));
const job = JSON.parse(fs.readFileSync(process.argv[2], 'utf8'));
const readme = fs.readFileSync(path.join(here, '..', 'README.md'), 'utf8');
const code = readme.split('<!-- prettier-ignore -->\n```js\n')[1].split('\n```')[0];
const bundle = await require('esbuild').build({
  stdin: { contents: code, resolveDir: path.join(here, '..'), loader: 'js' },
  bundle: true,
  format: 'esm',
  write: false,
  target: 'es2022',
  nodePaths: [modules],
  alias: { 'prt-lighting-three': path.join(here, '..', 'src', 'index.js') },
  logLevel: 'warning',
});
const script = bundle.outputFiles[0].text.replace(/<\/(script)/gi, '<\\/$1');
fs.writeFileSync(
  path.join(job.dir, 'index.html'),
  `<!doctype html><html><body style="margin:0"><script type="module">${script}</script></body></html>`,
);
const served = [];
const server = http.createServer((request, response) => {
  served.push(request.url);
  if (request.url === '/favicon.ico') {
    response.writeHead(204).end();
    return;
  }
  const file = path.join(
    job.dir,
    path.normalize(decodeURIComponent(request.url.split('?')[0])).replace(/^([/\\])+/, ''),
  );
  if (!file.startsWith(job.dir) || !fs.existsSync(file) || fs.statSync(file).isDirectory()) {
    response.writeHead(404).end();
    return;
  }
  const type = file.endsWith('.html') ? 'text/html' : 'application/octet-stream';
  response.writeHead(200, { 'Content-Type': type }).end(fs.readFileSync(file));
});
await new Promise((resolve) => server.listen(0, '127.0.0.1', resolve));
const url = `http://127.0.0.1:${server.address().port}/index.html`;
const summary = { console: [], requests: [] };
try {
  await withPage(job.chromium, job.dir, summary, async (page) => {
    await page.setViewport({ width: job.width, height: job.height });
    await page.evaluateOnNewDocument(() => {
      window.drawCalls = 0;
      const count = (name) => {
        const original = WebGL2RenderingContext.prototype[name];
        WebGL2RenderingContext.prototype[name] = function (...args) {
          window.drawCalls += 1;
          return original.apply(this, args);
        };
      };
      count('drawElements');
      count('drawArrays');
    });
    await page.goto(url, { waitUntil: 'load' });
    await page.waitForFunction(() => window.drawCalls > 0, { timeout: 300000, polling: 500 });
    const first = await page.evaluate(() => window.drawCalls);
    await page.evaluate(
      () => new Promise((r) => requestAnimationFrame(() => requestAnimationFrame(() => requestAnimationFrame(r)))),
    );
    summary.draws = [first, await page.evaluate(() => window.drawCalls)];
    await page.screenshot({ path: path.join(job.dir, 'example.png') });
  });
} finally {
  server.close();
}
summary.served = served;
console.log(JSON.stringify(summary));
