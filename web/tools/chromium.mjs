// Headless Chromium for the tests' scripts: software WebGL2, a throw-away profile, a watched page.
import fs from 'node:fs';
import path from 'node:path';
import { createRequire } from 'node:module';
import { fileURLToPath } from 'node:url';

const here = path.dirname(fileURLToPath(import.meta.url));
export const modules = process.env.PRT_NODE_MODULES || path.join(here, '..', '..', 'build', 'node', 'node_modules');
export const require = createRequire(path.join(modules, 'index.js'));

// Software WebGL2 in headless Chromium: ANGLE on SwiftShader, which Chromium allows only when asked.
export const CHROMIUM_FLAGS = [
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

// Runs work(page) in a fresh Chromium whose profile lives in profileParent; the page's console
// messages, errors and every request that is not file:, data: or blob: go into summary.console
// and summary.requests. The browser and its profile are removed whatever happens.
export async function withPage(executablePath, profileParent, summary, work) {
  const puppeteer = require('puppeteer-core');
  const userData = fs.mkdtempSync(path.join(profileParent, 'chromium-profile-'));
  const browser = await puppeteer.launch({
    executablePath,
    args: [...CHROMIUM_FLAGS, `--user-data-dir=${userData}`],
    headless: true,
    protocolTimeout: 600000,
    // Chromium's first start on a fresh machine (font and shader caches) took over puppeteer's
    // default 30 s once on 2 busy cores.
    timeout: 180000,
  });
  summary.console = summary.console || [];
  summary.requests = summary.requests || [];
  try {
    const page = await browser.newPage();
    page.on('console', (msg) => summary.console.push(`${msg.type()}: ${msg.text()}`));
    page.on('pageerror', (error) => summary.console.push(`pageerror: ${error.message}`));
    page.on('request', (request) => {
      if (!/^(file|data|blob):/.test(request.url())) summary.requests.push(request.url());
    });
    return await work(page);
  } finally {
    await browser.close();
    fs.rmSync(userData, { recursive: true, force: true });
  }
}
