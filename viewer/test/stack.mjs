// What the viewer's browser test and measurement share: free loopback ports, conica-server and
// the bridge as child processes (stopped together), headless Chromium.
import { spawn } from 'node:child_process';
import fs from 'node:fs';
import net from 'node:net';
import path from 'node:path';
import { fileURLToPath } from 'node:url';
import { chromium } from 'playwright-core';

export const viewerDir = path.resolve(path.dirname(fileURLToPath(import.meta.url)), '..');
export const sleep = (ms) => new Promise((r) => setTimeout(r, ms));

// Parses --name value pairs into the keys of `defaults` (kebab-case -> camelCase); `required`
// names options without a default.
export function parseArgs(argv, defaults, required = []) {
  const a = { ...defaults };
  for (let i = 2; i < argv.length; i += 2) {
    const k = argv[i].replace(/^--/, '').replace(/-([a-z])/g, (_, c) => c.toUpperCase());
    if (!(k in a) && !required.includes(k)) throw new Error(`unknown option ${argv[i]}`);
    if (i + 1 >= argv.length) throw new Error(`option ${argv[i]} needs a value`);
    a[k] = argv[i + 1];
  }
  for (const k of required) if (!a[k]) throw new Error(`--${k} is required`);
  return a;
}

export async function freePorts(n) {
  const servers = [];
  for (let i = 0; i < n; ++i) {
    const s = net.createServer();
    await new Promise((r) => s.listen(0, '127.0.0.1', r));
    servers.push(s);
  }
  const ports = servers.map((s) => s.address().port);
  await Promise.all(servers.map((s) => new Promise((r) => s.close(r))));
  return ports;
}

const children = [];
export function start(name, cmd, argv, env, logFile) {
  const out = fs.openSync(logFile, 'w');
  const child = spawn(cmd, argv, { env: { ...process.env, ...env }, stdio: ['ignore', out, out] });
  child.name = name;
  child.exited = new Promise((r) => child.on('exit', (code, sig) => r(code ?? sig)));
  children.push(child);
  return child;
}
export async function stopAll() {
  for (const c of children) {
    if (c.exitCode === null && c.signalCode === null) c.kill('SIGTERM');
  }
  for (const c of children) {
    const done = await Promise.race([c.exited, sleep(5000).then(() => 'timeout')]);
    if (done === 'timeout') c.kill('SIGKILL');
  }
}
export async function waitForLine(file, pattern, ms) {
  const end = Date.now() + ms;
  while (Date.now() < end) {
    if (fs.existsSync(file) && pattern.test(fs.readFileSync(file, 'utf8'))) return true;
    await sleep(100);
  }
  return false;
}

// conica-server (scene: a file, or builtin:NAME; serverArgs: more options, space separated) and
// the bridge in front of it, on free ports. Returns the endpoints and the page's URL, or null
// (with the bridge's log printed) on failure.
export async function startStack({ server, python, gen, scene, serverArgs = '', seconds, probeRadius, dir }) {
  const [pp, sp, cp, hp] = await freePorts(4);
  const ep = (p) => `tcp://127.0.0.1:${p}`;
  const sceneArgs = !scene ? ['--builtin', 'cube']
    : scene.startsWith('builtin:') ? ['--builtin', scene.slice(8)] : ['--scene', scene];
  start('server', server, [...sceneArgs, '--probe-endpoint', ep(pp), '--state-endpoint', ep(sp),
    '--control-endpoint', ep(cp), '--seconds', String(seconds), '--stats-seconds', '0', '--no-realtime',
    ...serverArgs.split(' ').filter(Boolean)],
  {}, path.join(dir, 'server.log'));
  start('bridge', python, [path.join(viewerDir, 'bridge.py'), '--state', ep(sp),
    '--control', ep(cp), '--port', String(hp), '--probe-radius', String(probeRadius),
    '--seconds', String(seconds)], { PYTHONPATH: gen }, path.join(dir, 'bridge.log'));
  if (!await waitForLine(path.join(dir, 'bridge.log'), /serving http/, 15000)) {
    console.log(fs.readFileSync(path.join(dir, 'bridge.log'), 'utf8'));
    return null;
  }
  return { probe: ep(pp), state: ep(sp), control: ep(cp), url: `http://127.0.0.1:${hp}/` };
}

// Headless Chromium with WebGL on SwiftShader (no GPU here). Without `gpu`, --disable-gpu: the
// compositor draws in software, which here is faster than compositing through SwiftShader too.
export function launchBrowser(executablePath, { gpu = false } = {}) {
  const args = ['--headless', '--no-sandbox', '--disable-quic', '--no-first-run',
    '--disable-background-networking', '--disable-component-update', '--disable-sync',
    '--enable-unsafe-swiftshader', '--use-angle=swiftshader'];
  if (!gpu) args.push('--disable-gpu');
  return chromium.launch({ executablePath, headless: true, args });
}
