// Measures the viewer in headless Chromium against conica-server + bridge: for each page variant
// (URL query, e.g. "aa=1&mat=standard" or "empty=1"; viewer.js lists them) a fresh page is
// connected, warmed up, then watched for --seconds. Prints display fps; state frames the bridge
// got from the server (srv/s); positions frames the page received, showed and dropped per second;
// median and 95th percentile of the apply and draw times, of the interval between drawn frames
// and of the frame age (bridge receipt -> drawn); and the draw cost: the median time of a draw
// waited for by a one-pixel read back (perf.drawCost). docs/viewer.md quotes its output.
//
//   node viewer/test/measure.mjs --server build/bin/conica-server --probe build/bin/conica-probe \
//     --gen build/proto/gen --scene configs/liver.pbtxt --variants 'aa=1&pdb=1&mat=standard;;empty=1'
// Options: --scene FILE or builtin:NAME, --server-args '...' (e.g. '--rate-hz 30'), --seconds s per
// variant (5), --warmup s (2), --viewport WxH (1280x800), --gpu 0|1 (1: without --disable-gpu,
// SwiftShader composites too), --press 1 (a scripted probe presses in a loop so the surface
// moves; --at/--axis/--depth as in viewer.test.mjs), --repeat n (variants measured round-robin n
// times), --json FILE (all summaries), --up z|y, --probe-radius m, --objects 1 (also the draw
// cost of each object of the scene alone: perf.drawCostByObject), --trace FILE (a Chromium trace
// of each measured window, FILE-ROUND-VARIANT.json, and the medians of the events that show where
// a frame's time goes: the page's wait for the canvas read back, SwiftShader's finish, the swap).
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import { launchBrowser, parseArgs, sleep, start, startStack, stopAll } from './stack.mjs';

const args = parseArgs(process.argv, {
  chromium: '/usr/bin/chromium', python: '/usr/bin/python3', scene: '', serverArgs: '', variants: '',
  seconds: '5', warmup: '2', viewport: '1280x800', gpu: '0', press: '0', at: '', axis: '',
  depth: '0.006', probeRadius: '0.005', up: 'z', repeat: '1', json: '', objects: '0', trace: '',
}, ['server', 'probe', 'gen']);

const f = (v, d = 1) => (Number.isFinite(v) ? v.toFixed(d) : '-');

// Chromium trace events that show where a displayed frame's time goes with software WebGL.
const TRACED = {
  'GLES2::ReadPixels': 'page waits for the canvas read back (software compositing)',
  'ContextVk::finishImpl': 'SwiftShader finishes the frame\'s draws',
  'ImageHelper::readPixelsImpl - CPU Readback': 'read back incl. that finish',
  'SkiaOutputSurfaceImplOnGpu::SwapBuffers': 'display swap (GPU-process compositing)',
  'Display::DrawAndSwap': 'display compositor frame',
  'ProxyMain::BeginMainFrame': 'page main-thread frame',
};
function traceSummary(file) {
  const data = JSON.parse(fs.readFileSync(file, 'utf8'));
  const events = Array.isArray(data) ? data : data.traceEvents;
  const lines = [];
  for (const [name, what] of Object.entries(TRACED)) {
    const d = events.filter((e) => e.ph === 'X' && e.name === name).map((e) => e.dur / 1000)
      .sort((a, b) => a - b);
    if (d.length) {
      lines.push(`    ${name} (${what}): ${d.length}x, p50 ${f(d[d.length >> 1], 2)} ms, `
        + `sum ${f(d.reduce((a, b) => a + b, 0), 0)} ms`);
    }
  }
  return lines.join('\n');
}

async function main() {
  const dir = fs.mkdtempSync(path.join(os.tmpdir(), 'conica-viewer-measure-'));
  const variants = args.variants.split(';');
  const perVariant = Number(args.warmup) + Number(args.seconds) + 4;
  const limit = 60 + 2 * perVariant * variants.length * Number(args.repeat);  // s; stopAll() ends them sooner
  const stack = await startStack({ ...args, seconds: limit, dir });
  if (!stack) throw new Error('the bridge did not start');
  let pressing = Number(args.press) > 0;
  const pressLoop = (async () => {
    for (let i = 0; pressing; ++i) {
      const a = ['--endpoint', stack.probe, '--script', 'press', '--depth', args.depth, '--hold', '1',
        '--realtime', '-o', path.join(dir, 'press.csv')];
      if (args.at) a.push('--at', args.at);
      if (args.axis) a.push('--axis', args.axis);
      await start('probe', args.probe, a, {}, path.join(dir, `probe${i % 2}.log`)).exited;
    }
  })();
  const [w, h] = args.viewport.split('x').map(Number);
  const browser = await launchBrowser(args.chromium, { gpu: args.gpu !== '0' });
  const rows = [];
  try {
    console.log(`scene ${args.scene || 'builtin:cube'}, viewport ${w}x${h}, gpu process ${args.gpu !== '0'}, `
      + `${args.seconds} s per variant after ${args.warmup} s`);
    console.log('variant                          fps  srv/s recv/s shown/s drop/s  apply p50/p95 ms  '
      + 'draw p50/p95 ms  interval p50/p95 ms  age p50/p95/max ms  draw cost ms');
    for (let r = 0; r < Number(args.repeat); ++r) {
      for (const v of variants) {
        const page = await browser.newPage({ viewport: { width: w, height: h } });
        await page.goto(`${stack.url}?up=${args.up}${v ? '&' + v : ''}`);
        await page.waitForFunction(() => window.conica?.framesReceived > 0, null, { timeout: 30000 })
          .catch(() => {});
        await sleep(1000 * Number(args.warmup));
        const traceFile = args.trace && `${args.trace.replace(/\.json$/, '')}-${r}-${variants.indexOf(v)}.json`;
        if (traceFile) {
          await browser.startTracing(page, { path: traceFile, categories: ['toplevel', 'gpu', 'viz',
            'cc', 'blink', 'disabled-by-default-gpu.service', 'gpu.angle'] });
        }
        await page.evaluate(() => window.conica.perf.reset());
        await sleep(1000 * Number(args.seconds));
        if (traceFile) await browser.stopTracing();
        const s = await page.evaluate(() => ({ ...window.conica.perf.summary(),
          nodes: window.conica.numNodes, triangles: window.conica.numTriangles,
          drawCostMs: window.conica.perf.drawCost(25) }));
        if (traceFile) console.log(`  trace ${traceFile}:\n${traceSummary(traceFile)}`);
        if (args.objects === '1') {
          s.drawCostByObject = await page.evaluate(() => window.conica.perf.drawCostByObject());
          console.log(`  draw cost by object, ms: ${Object.entries(s.drawCostByObject)
            .map(([k, x]) => `${k} ${f(x, 2)}`).join(', ')}`);
        }
        await page.close();
        rows.push({ variant: v, ...s });
        console.log(`${(v || '(default)').padEnd(30)} ${f(s.displayFps).padStart(5)} ${f(s.publishedPerS).padStart(6)} ${f(s.receivedPerS).padStart(6)} `
          + `${f(s.shownPerS).padStart(7)} ${f(s.droppedPerS).padStart(6)}  `
          + `${f(s.applyMs.p50, 2)}/${f(s.applyMs.p95, 2)}`.padEnd(18)
          + `${f(s.renderMs.p50, 2)}/${f(s.renderMs.p95, 2)}`.padEnd(17)
          + `${f(s.intervalMs.p50, 1)}/${f(s.intervalMs.p95, 1)}`.padEnd(21)
          + `${f(s.ageMs.p50, 0)}/${f(s.ageMs.p95, 0)}/${f(s.ageMs.max, 0)}`.padEnd(20)
          + `${f(s.drawCostMs, 2)}`);
      }
    }
    if (rows.length) console.log(`(${rows[0].nodes} nodes, ${rows[0].triangles} surface triangles)`);
    if (args.json) fs.writeFileSync(args.json, JSON.stringify(rows, null, 1));
  } finally {
    pressing = false;
    await browser.close();
  }
  await stopAll();
  await pressLoop;
}

try {
  await main();
} catch (e) {
  console.error(e.stack || String(e));
  await stopAll();
  process.exit(1);
}
