// node drive.mjs PORT FILE.glb...: runs bench.js in headless Chromium (puppeteer-core over
// Debian's /usr/bin/chromium, SwiftShader WebGL) on each file served at 127.0.0.1:PORT.
import puppeteer from 'puppeteer-core';
const browser = await puppeteer.launch({ executablePath: '/usr/bin/chromium', headless: true,
  args: ['--no-sandbox', '--use-angle=swiftshader', '--enable-unsafe-swiftshader'] });
const page = await browser.newPage();
await page.goto(`http://127.0.0.1:${process.argv[2]}/index.html`);
await page.waitForFunction('window.runBench !== undefined');
for (const f of process.argv.slice(3)) console.log(JSON.stringify(await page.evaluate((f) => window.runBench(f), f)));
await browser.close();
