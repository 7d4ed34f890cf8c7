// Builds the viewer into one self-contained HTML page (three.js bundled in, no network needed).
//
//   node web/build.mjs --out build/web/prt_viewer.html [--glb scene.glb]
//
// With --glb the file is embedded (base64), so the page opens it by itself from file://.
// esbuild and three come from build/node (scripts/setup_node.sh); scripts/build_web.sh runs this.
import fs from 'node:fs';
import path from 'node:path';
import { fileURLToPath } from 'node:url';
import { createRequire } from 'node:module';

const here = path.dirname(fileURLToPath(import.meta.url));
const modules = process.env.PRT_NODE_MODULES || path.join(here, '..', 'build', 'node', 'node_modules');
const require = createRequire(path.join(modules, 'index.js'));
const esbuild = require('esbuild');

function option(name) {
  const i = process.argv.indexOf(name);
  return i >= 0 ? process.argv[i + 1] : undefined;
}

const out = option('--out') || path.join(here, '..', 'build', 'web', 'prt_viewer.html');
const glb = option('--glb');
const result = await esbuild.build({
  entryPoints: [path.join(here, 'src', 'viewer.js')],
  bundle: true,
  format: 'iife',
  minify: true,
  write: false,
  target: 'es2020',
  nodePaths: [modules],
  legalComments: 'eof',
  logLevel: 'warning',
});
const script = result.outputFiles[0].text.replace(/<\/(script)/gi, '<\\/$1');
let html = fs.readFileSync(path.join(here, 'index.html'), 'utf8');
html = html.replace('/* PRT_VIEWER_SCRIPT */', () => script);
if (glb) {
  const data = fs.readFileSync(glb).toString('base64').replace(/.{1,120}/g, '$&\n');
  const name = path.basename(glb).replace(/[^\w.-]/g, '_');
  html = html.replace(
    '<!-- PRT_EMBEDDED_GLB -->',
    () => `<script id="prt-embedded" type="application/octet-stream" data-name="${name}">\n${data}</script>`,
  );
}
fs.mkdirSync(path.dirname(path.resolve(out)), { recursive: true });
const temp = `${out}.tmp`;
fs.writeFileSync(temp, html);
fs.renameSync(temp, out);
console.log(out);
