// The viewer page (server/viewer/index.html) against a running
// `dmmr-render --serve`, in headless Chromium (Debian's /usr/bin/chromium,
// driven by playwright-core; no browser is downloaded). run_viewer_test.sh
// starts the server and calls this; see there for what is checked.
//
// usage: node viewer_test.js --url URL --bin BIN_DIR --scene SCENE --home PATH
//          --work DIR --out DIR --clients N --page server/viewer/index.html
// (PATH: the --walkthrough the server was given, whose first point is home.)
'use strict';
const { chromium } = require('playwright-core');
const { spawnSync } = require('child_process');
const fs = require('fs');
const http = require('http');
const path = require('path');
const crypto = require('crypto');

const args = {};
for (let i = 2; i < process.argv.length; i += 2) args[process.argv[i].replace(/^--/, '')] = process.argv[i + 1];
for (const k of ['url', 'bin', 'scene', 'home', 'work', 'out', 'clients', 'page'])
  if (!args[k]) { console.error(`viewer_test.js: --${k} missing`); process.exit(2); }
const chromiumPath = process.env.DMMR_CHROMIUM || '/usr/bin/chromium';

let failures = 0;
function check(cond, what) {
  console.log(`${cond ? 'ok:  ' : 'FAIL:'} ${what}`);
  if (!cond) failures++;
  return cond;
}
// A failure after which the remaining checks make no sense.
class Fatal extends Error {}
function must(cond, what) { if (!check(cond, what)) throw new Fatal(what); }

// GET `url` with optional headers; resolves {status, body} or {upgraded: true}.
function get(url, headers = {}) {
  return new Promise((resolve, reject) => {
    const req = http.get(url, { headers }, (res) => {
      const chunks = [];
      res.on('data', (c) => chunks.push(c));
      res.on('end', () => resolve({ status: res.statusCode, body: Buffer.concat(chunks) }));
    });
    req.on('upgrade', (res, socket) => { socket.destroy(); resolve({ status: res.statusCode, upgraded: true }); });
    req.on('error', reject);
    req.setTimeout(10000, () => req.destroy(new Error(`GET ${url}: no answer in 10 s`)));
  });
}
const wsHeaders = () => ({
  Connection: 'Upgrade', Upgrade: 'websocket', 'Sec-WebSocket-Version': '13',
  'Sec-WebSocket-Key': crypto.randomBytes(16).toString('base64'),
});

function run(cmd, argv) {
  const r = spawnSync(cmd, argv, { encoding: 'utf8', timeout: 120000 });
  const out = `${r.stdout || ''}${r.stderr || ''}`.trim();
  return { status: r.error ? -1 : r.status, out: r.error ? String(r.error) : out };
}

// An AnimationPath line for `t` and a pose, numbers that read back as the same doubles.
const num = (x) => (Object.is(x, -0) ? '-0' : String(x));
const pathLine = (t, pose) => [t, ...pose.position, ...pose.rotation].map(num).join(' ') + '\n';

// Renders `pathFile` with dmmr-reference (from control point `from` on) and
// compares frame `from` with `png`, tolerance zero. Returns whether identical.
function sameAsReference(pathFile, from, fovy, png, what) {
  const ref = path.join(args.work, `reference-${path.basename(pathFile)}`);
  fs.rmSync(ref, { recursive: true, force: true });
  const refArgs = ['--scene', args.scene, '--walkthrough', pathFile, '--out', ref, '--no-progress',
    '--width', String(width), '--height', String(height), '--fovy', num(fovy)];
  if (from > 0) refArgs.push('--from-frame', String(from));
  const r = run(path.join(args.bin, 'dmmr-reference'), refArgs);
  if (!check(r.status === 0, `dmmr-reference renders ${what} (exit ${r.status})`)) { console.log(r.out); return false; }
  const frame = path.join(ref, `frame_${String(from).padStart(6, '0')}.png`);
  const c = run(path.join(args.bin, 'dmmr-compare'), [frame, png]);
  check(c.status === 0, `${what}: the still frame is pixel-identical to dmmr-reference's (dmmr-compare exit ${c.status}, 0 identical)`);
  if (c.status !== 0) console.log(c.out);
  return c.status === 0;
}

let width = 0, height = 0;

// The camera's view direction, its local -Z, in world space: minus the third
// column of the rotation matrix of unit quaternion q = [x, y, z, w].
function forward(q) {
  const [x, y, z, w] = q;
  return [-2 * (x * z + w * y), -2 * (y * z - w * x), -(1 - 2 * (x * x + y * y))];
}

async function main() {
  fs.mkdirSync(args.out, { recursive: true });
  const base = new URL(args.url);
  const token = base.searchParams.get('token');
  must(/^[0-9a-f]{32}$/.test(token || ''), `the URL's token is 128 bits in hex (${token})`);
  const origin = `${base.protocol}//${base.host}`;
  const wrong = token.replace(/^./, (c) => (c === '0' ? '1' : '0'));

  // The token guards the page and the socket; a request without it is refused.
  const page0 = await get(`${origin}/?token=${token}`);
  check(page0.status === 200, `GET / with the token: HTTP ${page0.status} (200)`);
  check(page0.body.equals(fs.readFileSync(args.page)),
    `the page served is ${path.basename(args.page)} as in the source tree, byte for byte (${page0.body.length} bytes)`);
  check((await get(`${origin}/?token=${wrong}`)).status === 403, 'GET / with a wrong token: HTTP 403');
  check((await get(`${origin}/`)).status === 403, 'GET / without a token: HTTP 403');
  const wsWrong = await get(`${origin}/ws?token=${wrong}`, wsHeaders());
  check(!wsWrong.upgraded && wsWrong.status === 403, `WebSocket upgrade with a wrong token: HTTP ${wsWrong.status} (403)`);
  const wsRight = await get(`${origin}/ws?token=${token}`, wsHeaders());
  check(wsRight.upgraded && wsRight.status === 101, `WebSocket upgrade with the token: HTTP ${wsRight.status} (101)`);

  const profile = fs.mkdtempSync(path.join(args.work, 'chromium-'));
  const context = await chromium.launchPersistentContext(profile, {
    executablePath: chromiumPath,
    headless: true,  // playwright passes --headless
    viewport: { width: 960, height: 600 },
    acceptDownloads: true,
    args: ['--no-sandbox', '--disable-gpu', '--disable-background-networking',
      '--disable-component-update', '--disable-sync'],
  });
  try {
    await browserChecks(context, args.url, wrong, origin);
  } finally {
    await context.close();
  }
}

async function browserChecks(context, url, wrong, origin) {
  const page = await context.newPage();
  const pageErrors = [];
  page.on('pageerror', (e) => pageErrors.push(String(e)));
  const refused = await page.goto(`${origin}/?token=${wrong}`);
  check(refused.status() === 403, `the browser loading the page with a wrong token gets HTTP ${refused.status()} (403)`);
  // (The refused page's favicon request, also refused, is no news.)
  page.on('console', (m) => {
    if (m.type() === 'error' && !/\/favicon\.ico/.test(m.location().url)) console.log(`page console: ${m.text()}`);
  });

  await page.goto(url);
  const V = 'window.dmmrViewer';
  const waitFor = async (what, fn, arg, timeout = 20000) => {
    try {
      await page.waitForFunction(fn, arg, { timeout, polling: 20 });
    } catch (e) {
      const state = await page.evaluate(() => ({ connected: dmmrViewer.connected, error: dmmrViewer.error,
        frames: dmmrViewer.frames, drawn: dmmrViewer.drawn, seq: dmmrViewer.seq, lastFrame: dmmrViewer.lastFrame }));
      throw new Fatal(`${what}: not within ${timeout / 1000} s; the page: ${JSON.stringify(state)}`);
    }
  };

  await waitFor('the first frame', () => dmmrViewer.drawn > 0);
  const hello = await page.evaluate(() => dmmrViewer.hello);
  width = hello.width; height = hello.height;
  check(hello.width === 256 && hello.height === 256, `Hello: the run's size, ${hello.width}x${hello.height} (256x256)`);
  check(hello.clients === Number(args.clients), `Hello: ${hello.clients} clients (${args.clients})`);
  check(JSON.stringify(hello.up) === '[0,0,1]', `Hello: up ${JSON.stringify(hello.up)} ([0,0,1])`);
  const homeLine = fs.readFileSync(args.home, 'utf8').split('\n')[0].trim().split(/\s+/).map(Number);
  check(JSON.stringify([...hello.home.position, ...hello.home.rotation]) === JSON.stringify(homeLine.slice(1)),
    `Hello: the home pose is --walkthrough's first point (${JSON.stringify(hello.home)})`);
  const first = await page.evaluate(() => dmmrViewer.lastFrame);
  check(first.seq === 1 && first.width === 256 && first.height === 256,
    `the first frame answers pose 1 at 256x256 (seq ${first.seq}, ${first.width}x${first.height})`);

  // The home pose's exact frame; it is the baseline the orbit must change.
  await waitFor('the still frame of the home pose', () => dmmrViewer.lastStill && dmmrViewer.lastStill.seq === dmmrViewer.seq);
  const homeStill = await page.evaluate(() => {
    const c = document.getElementById('view');
    window.__baseline = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
    return { seq: dmmrViewer.lastStill.seq, sent: dmmrViewer.lastStill.sent, counts: dmmrViewer.counts };
  });
  check(JSON.stringify(homeStill.sent.position) === JSON.stringify(hello.home.position) &&
        homeStill.sent.rotation.every((x, i) => Math.abs(x - hello.home.rotation[i]) < 1e-15),
    "the page's first pose is the Hello's home pose");
  check(homeStill.counts.still >= 1 && homeStill.counts.png >= 1, `the still frame came as PNG (${JSON.stringify(homeStill.counts)})`);
  const overlay = await page.evaluate(() => ({
    triangles: document.getElementById('triangles').textContent,
    kind: document.getElementById('kind').textContent,
    bars: document.querySelectorAll('#clients .client').length,
  }));
  check(Number(overlay.triangles.replace(/,/g, '')) > 0, `overlay: triangles drawn "${overlay.triangles}"`);
  check(overlay.kind === 'still (PNG, exact)', `overlay: frame kind "${overlay.kind}"`);
  check(overlay.bars === hello.clients, `overlay: ${overlay.bars} client bars, one per client`);

  // Orbit: record the flight, drag left-to-right on the canvas.
  await page.click('#record');
  const box = await page.locator('#view').boundingBox();
  const before = await page.evaluate(() => dmmrViewer.pose());
  const cx = box.x + box.width / 2, cy = box.y + box.height / 2;
  await page.mouse.move(cx, cy);
  await page.mouse.down();
  await page.mouse.move(cx + 15, cy + 6, { steps: 12 });
  await page.mouse.up();
  await page.waitForTimeout(100);  // the last pose goes out on the next animation frame
  const after = await page.evaluate(() => ({ pose: dmmrViewer.pose(), seq: dmmrViewer.seq }));
  must(after.seq > homeStill.seq + 1, `the drag sent poses (${after.seq - homeStill.seq})`);
  const dist = (p) => Math.hypot(...p.position.map((x, i) => x - p.target[i]));
  check(Math.abs(dist(after.pose) - dist(before)) < 1e-9 * dist(before) &&
        JSON.stringify(after.pose.target) === JSON.stringify(before.target),
    'orbit: the camera kept its target and its distance to it');
  const ahead = (p) => {
    const f = forward(p.rotation), d = dist(p);
    return f.reduce((s, x, i) => s + x * (p.target[i] - p.position[i]) / d, 0);
  };
  check(ahead(after.pose) > 1 - 1e-9, `orbit: the target is still straight ahead (cos ${ahead(after.pose)})`);

  // Wheel up zooms in (three.js's direction): 200 px, a distance factor of exp(-0.2).
  await page.mouse.wheel(0, -200);
  await page.waitForTimeout(100);
  const zoomed = await page.evaluate(() => ({ pose: dmmrViewer.pose(), seq: dmmrViewer.seq }));
  const ratio = dist(zoomed.pose) / dist(after.pose);
  check(Math.abs(ratio - Math.exp(-0.2)) < 1e-9 && ahead(zoomed.pose) > 1 - 1e-9 &&
        JSON.stringify(zoomed.pose.target) === JSON.stringify(before.target),
    `orbit: the wheel zoomed towards the target (distance x ${ratio.toFixed(4)}, exp(-0.2) = 0.8187)`);
  must(zoomed.seq === after.seq + 1, `the wheel sent one pose (${zoomed.seq - after.seq})`);

  // Right-drag pans: camera and target move together, across the view.
  await page.mouse.move(cx, cy);
  await page.mouse.down({ button: 'right' });
  await page.mouse.move(cx - 10, cy + 5, { steps: 3 });
  await page.mouse.up({ button: 'right' });
  await page.waitForTimeout(100);
  const panned = await page.evaluate(() => ({ pose: dmmrViewer.pose(), seq: dmmrViewer.seq }));
  const shift = panned.pose.position.map((x, i) => x - zoomed.pose.position[i]);
  const targetShift = panned.pose.target.map((x, i) => x - zoomed.pose.target[i]);
  const across = shift.reduce((s, x, i) => s + x * forward(zoomed.pose.rotation)[i], 0);
  check(Math.hypot(...shift) > 0 && shift.every((x, i) => Math.abs(x - targetShift[i]) < 1e-9 * dist(zoomed.pose)) &&
        Math.abs(across) < 1e-9 * Math.hypot(...shift) &&
        JSON.stringify(panned.pose.rotation) === JSON.stringify(zoomed.pose.rotation),
    `orbit: the right-drag panned camera and target by ${Math.hypot(...shift).toFixed(3)} across the view`);
  after.seq = panned.seq;

  await waitFor('a frame for the last pose (the pan after the drag and zoom)', (s) => dmmrViewer.lastFrame.seq === s, after.seq);
  const moved = await page.evaluate(() => {
    const c = document.getElementById('view');
    const now = c.getContext('2d').getImageData(0, 0, c.width, c.height).data, was = window.__baseline;
    let differ = 0;
    for (let i = 0; i < now.length; i += 4)
      if (now[i] !== was[i] || now[i + 1] !== was[i + 1] || now[i + 2] !== was[i + 2]) differ++;
    return { differ, pixels: now.length / 4, counts: dmmrViewer.counts };
  });
  check(moved.differ > moved.pixels / 20,
    `the frame after the orbit, zoom and pan differs from the first: ${moved.differ} of ${moved.pixels} pixels (over 5 %)`);
  check(moved.counts.jpeg >= 1, `frames while moving came as JPEG (${JSON.stringify(moved.counts)})`);

  // The exact frame for the last pose; the screenshot shows it with the overlay.
  await waitFor('the still frame after the orbit, zoom and pan', (s) => dmmrViewer.lastStill && dmmrViewer.lastStill.seq === s, after.seq);
  const shot = path.join(args.out, 'viewer.png');
  await page.screenshot({ path: shot });
  check(fs.statSync(shot).size > 1000, `screenshot ${shot}`);
  const still = await page.evaluate(() => ({
    seq: dmmrViewer.lastStill.seq, pose: dmmrViewer.lastStill.pose, sent: dmmrViewer.lastStill.sent,
    png: dmmrViewer.lastStill.png, canvas: document.getElementById('view').toDataURL('image/png').split(',')[1],
    last: dmmrViewer.lastFrame,
  }));
  must(still.sent !== null, `the page knows the pose it sent for seq ${still.seq}`);
  check(still.last.still && still.last.encoding === 'png', `the last frame drawn is the still PNG (${JSON.stringify(still.last.encoding)})`);
  check(JSON.stringify(still.pose.position) === JSON.stringify(still.sent.position) &&
        still.pose.rotation.every((x, i) => Math.abs(x - still.sent.rotation[i]) <= 1e-15) &&
        still.pose.fovy_deg === still.sent.fovy_deg,
    `the still frame's header echoes the pose sent (up to renormalisation): ${JSON.stringify(still.pose)}`);

  const stillPng = path.join(args.out, 'still.png'), canvasPng = path.join(args.out, 'canvas.png');
  fs.writeFileSync(stillPng, Buffer.from(still.png, 'base64'));
  fs.writeFileSync(canvasPng, Buffer.from(still.canvas, 'base64'));
  const shown = run(path.join(args.bin, 'dmmr-compare'), [canvasPng, stillPng]);
  check(shown.status === 0, `the canvas shows the still PNG's exact pixels (dmmr-compare exit ${shown.status})`);
  if (shown.status !== 0) console.log(shown.out);

  // The still frame's pose, as its header reports it, through dmmr-reference.
  const onePath = path.join(args.out, 'still.path');
  fs.writeFileSync(onePath, pathLine(0, still.pose));
  sameAsReference(onePath, 0, still.pose.fovy_deg, stillPng, "the still's pose");

  // The recorded flight: an AnimationPath whose last point is the still's pose.
  const download = page.waitForEvent('download', { timeout: 10000 });
  await page.click('#record');
  const recorded = path.join(args.out, 'recorded.path');
  await (await download).saveAs(recorded);
  const lines = fs.readFileSync(recorded, 'utf8').trim().split('\n').map((l) => l.split(' ').map(Number));
  check(lines.length >= 3 && lines.every((f) => f.length === 8 && f.every(Number.isFinite)),
    `recorded.path: ${lines.length} lines of 8 numbers (time x y z qx qy qz qw)`);
  check(lines.every((f, i) => i === 0 || f[0] >= lines[i - 1][0]), 'recorded.path: times never go backwards');
  const lastLine = lines[lines.length - 1];
  check(JSON.stringify(lastLine.slice(1)) === JSON.stringify([...still.sent.position, ...still.sent.rotation]),
    "recorded.path: the last point is the still's pose as sent, to the last bit");
  sameAsReference(recorded, lines.length - 1, still.sent.fovy_deg, stillPng, 'the recorded flight\'s last point');

  // Fly: W moves along the view; Home returns to the home pose and its exact frame again.
  await page.keyboard.press('m');
  check(await page.evaluate(() => dmmrViewer.mode()) === 'fly', 'M switches to fly mode');
  const flyFrom = await page.evaluate(() => dmmrViewer.pose());
  await page.keyboard.down('w');
  await page.waitForTimeout(300);
  await page.keyboard.up('w');
  const flyTo = await page.evaluate(() => dmmrViewer.pose());
  const step = flyTo.position.map((x, i) => x - flyFrom.position[i]);
  const fwd = forward(flyTo.rotation);
  const stepLen = Math.hypot(...step);
  check(stepLen > 0 && step.reduce((s, x, i) => s + x * fwd[i], 0) > 0.999 * stepLen,
    `fly: W moved the camera ${stepLen.toFixed(3)} along its view direction`);
  // Dragging in fly mode turns the camera in place; right is right.
  await page.mouse.move(cx, cy);
  await page.mouse.down();
  await page.mouse.move(cx + 20, cy, { steps: 3 });
  await page.mouse.up();
  const looked = await page.evaluate(() => dmmrViewer.pose());
  const f0 = forward(flyTo.rotation), f1 = forward(looked.rotation);
  const turnedRight = (f0[0] * f1[1] - f0[1] * f1[0]) < 0;  // about +Z: clockwise seen from above
  check(JSON.stringify(looked.position) === JSON.stringify(flyTo.position) && turnedRight &&
        Math.abs(f1[2] - f0[2]) < 1e-9,
    'fly: dragging right turned the view right about the up axis, in place');
  await page.keyboard.press('h');
  const homeAgain = await page.evaluate(() => ({ pose: dmmrViewer.pose(), hello: dmmrViewer.hello.home }));
  check(JSON.stringify(homeAgain.pose.position) === JSON.stringify(homeAgain.hello.position),
    'H returns the camera to the home position');
  await page.waitForTimeout(100);
  const homeSeq = await page.evaluate(() => dmmrViewer.seq);
  await waitFor('the still frame of the home pose, again', (s) => dmmrViewer.lastStill && dmmrViewer.lastStill.seq === s, homeSeq);
  const same = await page.evaluate(() => {
    const c = document.getElementById('view');
    const now = c.getContext('2d').getImageData(0, 0, c.width, c.height).data, was = window.__baseline;
    let differ = 0;
    for (let i = 0; i < now.length; i += 4)
      if (now[i] !== was[i] || now[i + 1] !== was[i + 1] || now[i + 2] !== was[i + 2]) differ++;
    return differ;
  });
  check(same === 0, `back home, the still frame equals the first one (${same} pixels differ)`);

  const end = await page.evaluate(() => ({ error: dmmrViewer.error, connected: dmmrViewer.connected }));
  check(end.connected && end.error === null, `the page is still connected, no error (${end.error})`);
  check(pageErrors.length === 0, `no uncaught errors in the page (${pageErrors.join('; ')})`);
}

main().then(() => {
  console.log(failures ? `viewer_test: ${failures} checks failed` : 'viewer_test: all checks passed');
  process.exit(failures ? 1 : 0);
}, (e) => {
  console.log(e instanceof Fatal ? `viewer_test: stopped: ${e.message}` : `viewer_test: ${e.stack || e}`);
  process.exit(1);
});
