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

function fail(message) {
  console.error(`build_web: ${message}`);
  process.exit(2);
}

/** The .glb's bytes, after checking it is a binary glTF with PRT lighting (docs/export.md). */
function readGLB(file) {
  let bytes;
  try {
    bytes = fs.readFileSync(file);
  } catch (error) {
    fail(`cannot read '${file}': ${error.code === 'ENOENT' ? 'no such file' : error.message}`);
  }
  if (bytes.length < 20 || bytes.toString('latin1', 0, 4) !== 'glTF' || bytes.readUInt32LE(16) !== 0x4e4f534a) {
    fail(`'${file}' is not a binary glTF (.glb) file`);
  }
  let json;
  try {
    json = JSON.parse(bytes.toString('utf8', 20, 20 + bytes.readUInt32LE(12)));
  } catch (error) {
    fail(`'${file}' has a broken JSON chunk: ${error.message}`);
  }
  if (!(json.scenes || []).some((scene) => scene.extras && scene.extras.PRT_lighting)) {
    fail(`'${file}' has no PRT lighting: export it with PRT Lighting (File > Export > PRT Lighting (.glb))`);
  }
  return bytes;
}

const out = option('--out') || path.join(here, '..', 'build', 'web', 'prt_viewer.html');
const glb = option('--glb');
const glbBytes = glb ? readGLB(glb) : null;
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
  const data = glbBytes.toString('base64').replace(/.{1,120}/g, '$&\n');
  const name = path.basename(glb).replace(/[^\w.-]/g, '_');
  html = html.replace(
    '<!-- PRT_EMBEDDED_GLB -->',
    () => `<script id="prt-embedded" type="application/octet-stream" data-name="${name}">\n${data}</script>`,
  );
}
// Written to a temporary name and renamed: a failure leaves no partial page (an old one is kept).
const temp = `${out}.${process.pid}.tmp`;
try {
  fs.mkdirSync(path.dirname(path.resolve(out)), { recursive: true });
  fs.writeFileSync(temp, html);
  fs.renameSync(temp, out);
} catch (error) {
  try {
    fs.rmSync(temp, { force: true });
  } catch {
    // (no folder, so no file)
  }
  const reasons = {
    EACCES: 'permission denied',
    EEXIST: 'a part of its folder is a file',
    ENOTDIR: 'a part of its folder is a file',
  };
  fail(`cannot write '${out}': ${reasons[error.code] || error.message}`);
}
console.log(out);
