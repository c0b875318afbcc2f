// accelcal's pages in a real browser (Debian's chromium, driven by
// playwright-core), against a real accelcal holding the paper's submission
// and a synthetic history. Run by tests/ui/run.sh, which starts the servers.
//
// It signs in, opens the fleet, sensor, calibration and certificate pages
// and checks that the plotted points are the history the API serves, that
// the tables hold the stored numbers, that no page logs a console error or
// asks for anything beyond the server, and that axe-core finds no serious or
// critical accessibility violation (light and dark); it saves full-page
// screenshots (light, dark, phone) under target/ui-screenshots/. It also
// checks that a wrong token, an expired or revoked session and form posts
// without their CSRF token are refused.

import assert from 'node:assert/strict';
import { execFileSync } from 'node:child_process';
import { createHash } from 'node:crypto';
import fs from 'node:fs';
import path from 'node:path';
import { chromium } from 'playwright-core';

const BASE = process.env.ACCELCAL_URL;
const SHORT = process.env.ACCELCAL_SHORT_SESSION_URL; // a database of its own, 1 s sessions
const ADMIN = process.env.ACCELCAL_ADMIN_TOKEN;
const SHOTS = process.env.SCREENSHOTS ?? 'target/ui-screenshots';
const CHROMIUM = process.env.CHROMIUM ?? '/usr/bin/chromium';
const AXE = fs.readFileSync(new URL('./node_modules/axe-core/axe.min.js', import.meta.url), 'utf8');

let checks = 0;
const ok = (what) => { checks += 1; console.log(`ok ${checks} - ${what}`); };

// ---------------------------------------------------------------- the API
async function api(method, p, { token = ADMIN, body, type = 'application/json' } = {}) {
  const res = await fetch(BASE + p, {
    method,
    headers: { Authorization: `Bearer ${token}`, ...(body ? { 'Content-Type': type } : {}) },
    body,
  });
  const text = await res.text();
  let json = null;
  try { json = JSON.parse(text); } catch { /* not JSON */ }
  return { status: res.status, json, text };
}

async function must(status, promise, what) {
  const r = await promise;
  assert.equal(r.status, status, `${what}: ${r.text.slice(0, 400)}`);
  return r.json;
}

// A deterministic synthetic sensor: k0 drifts 2e-5 per year, one test (the
// seventh) is 1.5e-4 off, small noise from a fixed-seed generator.
let seed = 20261122;
const noise = () => { seed = (seed * 1103515245 + 12345) % 2147483648; return (seed / 2147483648 - 0.5) * 2e-6; };
function synthetic(i) {
  const t = i / 6; // every two months
  const k0 = 1e-4 + 2e-5 * t + (i === 6 ? 1.5e-4 : 0);
  const ki = 1.0 + 1e-5 * t;
  const kp = 2e-3;
  const positions = [0, 90, 180, 270];
  const out = (deg) => {
    const th = (deg * Math.PI) / 180;
    return k0 + ki * -Math.sin(th) + kp * Math.cos(th);
  };
  const day = new Date(Date.UTC(2024, 0, 15) + i * 61 * 86400e3).toISOString();
  return {
    sensor_id: 'SYN-001',
    performed_at: day,
    unit: 'mA',
    station_id: 'LAB-2',
    sensor_type: 'SYN',
    stand: { id: 'DH-2', angle_std_arcsec: 3, gravity_rel_std: 2e-6 },
    positions: positions.map((angle_deg) => ({ angle_deg })),
    runs: [0, 1, 2, 3].map(() => ({ readings: positions.map((d) => [out(d) + noise(), out(d) + noise()]) })),
  };
}

// ------------------------------------------------------------ the browser
const browser = await chromium.launch({
  executablePath: CHROMIUM,
  args: ['--no-sandbox', '--disable-gpu', '--disable-quic', '--no-first-run',
    '--disable-background-networking', '--disable-component-update', '--disable-sync'],
});
const offsite = [];
const problems = [];
// Pages where a test provokes a 4xx on purpose (chromium logs those).
const provoked = new Set();

async function newContext(options = {}) {
  const context = await browser.newContext({ baseURL: BASE, ...options });
  await context.route('**/*', (route) => {
    const url = new URL(route.request().url());
    if (url.hostname !== '127.0.0.1' && url.hostname !== 'localhost') {
      offsite.push(url.href);
      return route.abort();
    }
    return route.continue();
  });
  context.on('page', watch);
  return context;
}

function watch(page) {
  page.on('console', (m) => {
    const expected = provoked.has(page.url()) && /^Failed to load resource: the server responded with a status of 4\d\d/.test(m.text());
    if ((m.type() === 'error' || m.type() === 'warning') && !expected) problems.push(`${page.url()}: console ${m.type()}: ${m.text()}`);
  });
  page.on('pageerror', (e) => problems.push(`${page.url()}: ${e.message}`));
  page.on('response', (r) => { if (r.status() >= 500) problems.push(`${r.url()}: ${r.status()}`); });
}

async function signIn(page, token, base = BASE) {
  await page.goto(`${base}/ui/sensors`);
  assert.match(page.url(), /\/ui\/login\?next=/, 'a page asks to sign in first');
  await page.fill('#token', token);
  const [res] = await Promise.all([page.waitForNavigation(), page.click('button[type=submit]')]);
  return res;
}

async function axe(page, what) {
  const result = await page.evaluate(`${AXE}; axe.run(document, { resultTypes: ['violations'] })`);
  const bad = result.violations.filter((v) => v.impact === 'serious' || v.impact === 'critical');
  assert.deepEqual(
    bad.map((v) => `${v.id}: ${v.help} (${v.nodes.map((n) => n.target.join(' ')).slice(0, 3).join('; ')})`),
    [],
    `axe-core on ${what}`,
  );
}

// The pages' event stream asked for without a session cookie.
const anonStream = () => fetch(`${BASE}/ui/events`, { redirect: 'manual' });

const num = (text) => Number(text.trim().replace('−', '-'));
const close = (got, want, rel, what) => assert.ok(
  Math.abs(got - want) <= rel * Math.abs(want) + 1e-300, `${what}: ${got} is not ${want} (to ${rel})`);

try {
  // --------------------------------------------------------------- seed
  const reader = (await must(201, api('POST', '/v1/tokens', { body: JSON.stringify({ role: 'reader', label: 'ui' }) }), 'reader token')).token;
  await must(201, api('PUT', '/v1/sensor-types/NAV', { body: fs.readFileSync('examples/sensor-type-nav.json') }), 'type NAV');
  await must(201, api('PUT', '/v1/sensor-types/SYN', {
    body: JSON.stringify({ label: 'Synthetic', unit: 'mA', limits: { k0: { min: -5e-4, max: 5e-4 }, ki: { min: 0.999, max: 1.001 } }, decision_rule: 'guarded', interval_days: 180 }),
  }), 'type SYN');
  const paperBytes = fs.readFileSync('examples/paper-table1.json');
  const paper = await must(201, api('POST', '/v1/calibrations', { body: paperBytes }), 'paper');
  const recal = await must(201, api('POST', '/v1/calibrations', { body: fs.readFileSync('examples/paper-recalibration.json') }), 'recalibration');
  for (let i = 0; i < 12; i += 1) {
    await must(201, api('POST', '/v1/calibrations', { body: JSON.stringify(synthetic(i)) }), `synthetic ${i}`);
  }
  const triad = await must(201, api('POST', '/v1/calibrations/triad', { body: fs.readFileSync('examples/triad-recording.json') }), 'triad');
  const thermal = await must(201, api('POST', '/v1/calibrations/thermal', { body: fs.readFileSync('examples/thermal-chamber.json') }), 'temperature model');
  await must(201, api('PUT', '/v1/sensor-types/IMU-TC', {
    body: JSON.stringify({ label: 'MEMS IMU', unit: 'm/s2', limits: { k0: { min: -0.5, max: 0.5 }, ki: { min: 9.6, max: 10.0 }, kp: { min: -0.1, max: 0.1 } }, decision_rule: 'guarded', coverage_probability: 0.9545, interval_days: 365 }),
  }), 'type IMU-TC');
  const thermalTriad = await must(201, api('POST', '/v1/calibrations/thermal/triad', {
    body: JSON.stringify({ ...JSON.parse(fs.readFileSync('examples/thermal-triad.json')), sensor_type: 'IMU-TC' }),
  }), 'triad temperature model');
  const history = (await must(200, api('GET', '/v1/sensors/SYN-001/calibrations?limit=500'), 'history')).items;
  const stability = await must(200, api('GET', '/v1/sensors/SYN-001/stability'), 'stability');
  const sensors = (await must(200, api('GET', '/v1/sensors'), 'sensors')).items;
  assert.equal(history.length, 12);
  ok('seeded: the paper, its recalibration, twelve synthetic calibrations, a triad, a temperature model and a triad\'s');

  // ------------------------------------------------------------ sign in
  const context = await newContext({ viewport: { width: 1280, height: 900 } });
  const page = await context.newPage();
  await signIn(page, reader);
  assert.match(page.url(), /\/ui\/sensors$/);
  const cookies = await context.cookies();
  const session = cookies.find((c) => c.name === 'accelcal_session');
  assert.ok(session, 'a session cookie');
  assert.equal(session.httpOnly, true);
  assert.equal(session.sameSite, 'Strict');
  assert.equal(session.path, '/ui');
  ok('a reader token signs in; the session cookie is HttpOnly, SameSite=Strict, Path=/ui');

  // -------------------------------------------------------------- fleet
  const rows = await page.$$eval('#fleet tbody tr', (trs) => trs.map((tr) => tr.dataset.sensorId));
  assert.deepEqual(rows, sensors.map((s) => s.sensor_id));
  for (const s of sensors) {
    const status = await page.$eval(`#fleet tr[data-sensor-id="${s.sensor_id}"] td:last-child`, (td) => td.textContent.trim());
    assert.equal(status, s.status.replace('_', ' '), `status of ${s.sensor_id}`);
  }
  await page.fill('#search', 'syn');
  await Promise.all([page.waitForNavigation(), page.click('form.filters button')]);
  assert.deepEqual(await page.$$eval('#fleet tbody tr', (trs) => trs.map((tr) => tr.dataset.sensorId)), ['SYN-001']);
  const synStatus = sensors.find((s) => s.sensor_id === 'SYN-001').status;
  await page.goto(`/ui/sensors?status=${synStatus}`);
  const byStatus = await page.$$eval('#fleet tbody tr', (trs) => trs.map((tr) => tr.dataset.sensorId));
  assert.deepEqual(byStatus, sensors.filter((s) => s.status === synStatus).map((s) => s.sensor_id));
  ok('fleet: every sensor with its status; search and the status filter select what the API selects');

  // ------------------------------------------------------------- sensor
  await page.goto('/ui/sensors/SYN-001');
  for (const term of ['k0', 'ki', 'kp']) {
    const points = await page.$$eval(`#chart-${term} circle.pt`, (cs) => cs.map((c) => ({
      id: c.dataset.calibrationId, y: c.dataset.y, flagged: c.classList.contains('flagged'),
    })));
    assert.equal(points.length, history.length, `${term}: one point per calibration`);
    const byId = new Map(history.map((c) => [c.id, c]));
    for (const p of points) {
      const c = byId.get(p.id);
      assert.ok(c, `${term}: point ${p.id} is a calibration of the sensor`);
      assert.equal(Number(p.y), c.coefficients[term], `${term}: the plotted value of ${p.id} is the stored one`);
    }
    const flagged = points.filter((p) => p.flagged).map((p) => p.id).sort();
    assert.deepEqual(flagged, [...stability.terms[term].control.out_of_control].sort(), `${term}: flagged points`);
    const cells = await page.$$eval(`table[data-term="${term}"] tbody tr`, (trs) => trs.map((tr) => ({
      id: tr.dataset.calibrationId, v: tr.querySelector('td[data-value]').dataset.value,
    })));
    assert.deepEqual(cells.map((c) => [c.id, Number(c.v)]).sort(), points.map((p) => [p.id, Number(p.y)]).sort(), `${term}: the table beside the chart`);
    assert.equal(await page.locator(`#chart-${term} line.rule.limit`).count(), 2, `${term}: two control limits`);
    assert.equal(await page.locator(`#chart-${term} line.segment.drift`).count(), 1, `${term}: the drift line`);
  }
  assert.ok(stability.terms.k0.control.out_of_control.includes(history.find((c) => c.performed_at.startsWith('2025-01')).id),
    'the synthetic outlier is out of control');
  const meanCell = await page.$eval('#stability tr[data-term="k0"] td', (td) => td.textContent);
  close(num(meanCell), stability.terms.k0.mean, 5e-9, 'stability mean of k0');
  const driftCell = await page.$eval('#stability tr[data-term="k0"] td:nth-of-type(5)', (td) => td.textContent);
  close(num(driftCell), stability.terms.k0.drift_per_year, 5e-5, 'drift of k0 per year');
  ok('sensor: every plotted point is a stored calibration at its stored value, flagged as the API flags it; the tables agree');

  // -------------------------------------------------------- calibration
  await page.goto(`/ui/calibrations/${paper.id}`);
  const fused = await page.$$eval('#estimates tr[data-row="fused"] td.num', (tds) => tds.map((td) => td.textContent));
  assert.equal(fused.length, 3);
  ['k0', 'ki', 'kp'].forEach((t, k) => close(num(fused[k]), paper.fused.coefficients[t], 5e-9, `fused ${t}`));
  close(num(fused[1]), -1.216154046, 5e-9, 'the paper\'s fused K1');
  const se = await page.$$eval('#estimates tr[data-row="fused-std-error"] td.num', (tds) => tds.map((td) => td.textContent));
  ['k0', 'ki', 'kp'].forEach((t, k) => close(num(se[k]), paper.fused.std_errors[t], 5e-5, `fused SE ${t}`));
  close(num(se[2]), 6.3637e-6, 5e-5, 'the fused SE of α from Table 1');
  const runRows = await page.$$eval('#estimates tbody tr[data-run]', (trs) => trs.length);
  assert.equal(runRows, 6);
  const residuals = await page.$$eval('#residuals circle.pt', (cs) => cs.map((c) => [Number(c.dataset.run), Number(c.dataset.position), Number(c.dataset.y)]));
  assert.equal(residuals.length, 6 * 4);
  for (const [j, i, y] of residuals) assert.equal(y, paper.runs[j].residuals[i], `residual of run ${j} at position ${i}`);
  ok('calibration: the paper\'s fused coefficients and standard errors, every run, every residual');

  await page.goto(`/ui/calibrations/${recal.id}`);
  const budget = await page.$$eval('#budget tbody tr', (trs) => trs.map((tr) => [tr.dataset.term, tr.querySelector('td:last-child').textContent]));
  for (const [t, u] of budget) close(num(u), recal.uncertainty.terms[t].expanded, 5e-5, `expanded U of ${t}`);
  const verdicts = await page.$$eval('#decision tbody tr', (trs) => trs.map((tr) => [tr.dataset.term, tr.querySelector('td:last-child').textContent.trim()]));
  assert.deepEqual(Object.fromEntries(verdicts), Object.fromEntries(Object.entries(recal.decision.terms).map(([t, d]) => [t, d.verdict])));
  const asFound = await page.$$eval('#as-found tbody tr td:last-child', (tds) => tds.map((td) => td.textContent));
  recal.as_found.positions.forEach((p, i) => close(num(asFound[i]), p.error_g, 5e-5, `as found at position ${i}`));
  ok('calibration: uncertainty budget, decision and as found as stored');

  // -------------------------------------------------------- certificate
  await page.goto(`/ui/calibrations/${recal.id}`);
  await Promise.all([page.waitForNavigation(), page.click('a[href$="/certificate"]')]);
  const text = await page.textContent('body');
  const sha = createHash('sha256').update(fs.readFileSync('examples/paper-recalibration.json')).digest('hex');
  assert.ok(text.includes(sha), 'the SHA-256 of the submission as sent');
  assert.ok(text.includes(`${BASE}/v1/calibrations/${recal.id}/certificate`), 'its own URL');
  assert.ok(text.includes('PAPER-2005') && text.includes('NAV') && text.includes('DH-1'), 'sensor, type, stand');
  assert.ok(/accelcal \d+\.\d+\.\d+/.test(text), 'the accelcal version');
  // Columns: value, standard error, u_c, ν_eff, k, p, U, unit.
  const certRows = await page.$$eval('#certificate-results tbody tr', (trs) => trs.map((tr) => [tr.dataset.term, ...[0, 3, 4, 5, 6, 7].map((i) => tr.querySelectorAll('td')[i].textContent)]));
  const units = { k0: 'output', ki: 'output/g', kp: 'output/g', ko: 'output/g', kii: 'output/g²', kiii: 'output/g³' };
  for (const [t, v, nu, k, p, u, unit] of certRows) {
    // Rounded to the place of U's second significant digit (GUM 7.2.6).
    const b = recal.uncertainty.terms[t];
    assert.ok(Math.abs(num(v) - recal.fused.coefficients[t]) <= b.expanded / 20, `certificate value of ${t}: ${v} is not ${recal.fused.coefficients[t]} to U/20`);
    close(num(u), b.expanded, 0.05, `certificate U of ${t}`);
    assert.equal(unit, units[t], `the unit of ${t}`);
    // Each coefficient's ν_eff, k and p as the result states them (issue 42).
    assert.equal(nu, b.effective_dof === null ? '∞' : String(b.effective_dof), `ν_eff of ${t}`);
    close(num(k), b.coverage_factor, 0.005, `k of ${t}`);
    assert.equal(p, `${(100 * b.coverage_probability).toFixed(2)} %`, `p of ${t}`);
  }
  assert.ok(text.includes('for a coverage probability of 95.45 %'), 'the coverage probability stated');
  assert.ok(text.includes('The results relate only to the item calibrated'), 'the scope of the results');
  assert.ok(text.includes('Environmental conditions') && text.includes('Metrological traceability'), 'conditions and traceability');
  assert.ok(text.includes(`End of certificate No. ${recal.id}`), 'the end marker');
  const pdf = await page.pdf({ format: 'A4' });
  assert.ok(pdf.length > 10000, 'the certificate prints');
  fs.mkdirSync(SHOTS, { recursive: true });
  const pdfPath = path.join(SHOTS, 'certificate.pdf');
  fs.writeFileSync(pdfPath, pdf);
  // Every printed page carries the title and number, and "Page n of N".
  const printed = execFileSync('pdftotext', ['-layout', pdfPath, '-'], { encoding: 'utf8' }).split('\f').filter((p) => p.trim());
  assert.ok(printed.length >= 2, `the certificate prints on ${printed.length} pages`);
  printed.forEach((p, i) => {
    assert.ok(p.includes(`Calibration certificate No. ${recal.id}`), `page ${i + 1} carries the number`);
    assert.ok(p.includes(`Page ${i + 1} of ${printed.length}`), `page ${i + 1} says "Page ${i + 1} of ${printed.length}"`);
  });
  assert.ok(printed[printed.length - 1].includes('End of certificate'), 'the end marker on the last page');
  ok(`certificate: SHA-256, own URL, sensor, type, stand, version, values rounded to U with units, k and its probability; prints to A4 on ${printed.length} pages, each numbered`);

  // -------------------------------------------------------------- review
  // A reviewer signs the paper's calibration on its page, typing the token
  // again; the page then shows the state and the signature, and passes axe
  // with the form on it.
  const reviewer = (await must(201, api('POST', '/v1/tokens', { body: JSON.stringify({ role: 'reviewer', holder: 'Rita Reviewer' }) }), 'reviewer token')).token;
  const rctx = await newContext({ viewport: { width: 1280, height: 900 } });
  const rpage = await rctx.newPage();
  await signIn(rpage, reviewer);
  await rpage.goto(`/ui/calibrations/${paper.id}`);
  assert.equal((await rpage.textContent('#review .badge')).trim(), 'submitted');
  await axe(rpage, 'calibration with the review form');
  await rpage.check('input[name=act][value=approve]');
  await rpage.fill('#review-comment', 'Residuals and budget checked.');
  await rpage.fill('#review-token', reviewer);
  await Promise.all([rpage.waitForNavigation(), rpage.click('form.review button[type=submit]')]);
  assert.equal((await rpage.textContent('#review .badge')).trim(), 'approved');
  const signed = await rpage.$$eval('#signatures tbody tr', (trs) => trs.map((tr) => [...tr.querySelectorAll('td')].map((td) => td.textContent.trim())));
  assert.equal(signed.length, 1);
  assert.equal(signed[0][0], 'Rita Reviewer');
  assert.equal(signed[0][1], 'reviewer');
  assert.equal(signed[0][4], 'Residuals and budget checked.');
  const record = await must(200, api('GET', `/v1/calibrations/${paper.id}/signatures`), 'signatures');
  assert.equal(record.state, 'approved');
  assert.equal(record.signatures[0].holder, 'Rita Reviewer');
  ok('review: a reviewer signs on the page with the token typed again; the page and the API show the approval');

  // -------------------------------------------------------------- triad
  await page.goto(`/ui/calibrations/${triad.id}`);
  assert.match(await page.textContent('h1'), /Triad calibration of IMU-DEMO-1/);
  const shownB = await page.$$eval('#triad-b tbody td', (tds) => tds.map((td) => Number(td.textContent)));
  for (let m = 0; m < 3; m += 1) close(shownB[2 * m], triad.b[m], 1e-8, `b[${m}] on the page`);
  const shownT = await page.$$eval('#triad-T tbody tr', (trs) => trs.map((tr) => Number(tr.querySelectorAll('td')[0].textContent)));
  for (let m = 0; m < 3; m += 1) close(shownT[m], triad.T[m][0], 1e-8, `T[${m}][0] on the page`);
  const download = await page.request.get(`/ui/calibrations/${triad.id}/export/px4`);
  assert.equal(download.status(), 200);
  assert.match(await download.text(), /CAL_ACC0_XOFF/);
  assert.ok(await page.$('#dcc-link'), 'the triad page links its Digital Calibration Certificate');
  await page.goto('/ui/sensors/IMU-DEMO-1');
  assert.ok(await page.$('#stability tr[data-term="b_x"]'), 'the triad sensor shows stability element by element');
  // A gravity-magnitude triad: b and S on and below the diagonal charted,
  // the frame convention's zeros not.
  const charted = await page.$$eval('figure.chart', (figures) => figures.map((f) => f.id));
  assert.deepEqual(charted, ['chart-b_x', 'chart-b_y', 'chart-b_z', 'chart-S_xx', 'chart-S_yx', 'chart-S_yy', 'chart-S_zx', 'chart-S_zy', 'chart-S_zz']);
  const plotted = Number(await page.getAttribute('table[data-term="b_x"] tr[data-calibration-id] td[data-value]', 'data-value'));
  close(plotted, triad.b[0], 1e-12, 'b_x charted as stored');
  ok('triad: the page shows b and T as stored, offers the firmware files and the DCC, and the sensor page charts and lists its elements');

  // --------------------------------------------------- temperature model
  await page.goto(`/ui/calibrations/${thermal.id}`);
  const polynomials = await page.$$eval('#thermal-polynomials tbody tr', (trs) => trs.map((tr) => [tr.querySelector('th').textContent, tr.querySelectorAll('td')[3].textContent]));
  assert.deepEqual(polynomials.map((r) => r[0]), ['k0', 'ki', 'kp'], 'one polynomial per term');
  const k0 = thermal.thermal.coefficients.k0;
  close(num(polynomials[0][1]), k0.coefficients[1], 1e-3, 'a_1 of k0 on the page');
  assert.equal(await page.$$eval('#thermal-set-points tbody tr', (trs) => trs.length), 5, 'five set points');
  assert.ok(await page.$('#dcc-link'), 'the temperature model links its DCC');
  await Promise.all([page.waitForNavigation(), page.click('a[href$="/certificate"]')]);
  const aRows = await page.$$eval('#certificate-results tbody tr', (trs) => trs.map((tr) => [tr.dataset.term, tr.querySelectorAll('td')[0].textContent, tr.querySelectorAll('td')[6].textContent]));
  const wantRows = Object.entries(thermal.thermal.coefficients).flatMap(([t, p]) => p.coefficients.map((_, d) => `${t}_a${d}`));
  assert.deepEqual(aRows.map((r) => r[0]), wantRows, 'a row per a_d of every polynomial');
  const [, a1, a1U] = aRows.find((r) => r[0] === 'k0_a1');
  assert.ok(Math.abs(num(a1) - k0.coefficients[1]) <= num(a1U) / 20, `k0_a1 on the certificate: ${a1} is not ${k0.coefficients[1]} to U/20`);
  assert.equal(await page.$$eval('#thermal-set-points tbody tr', (trs) => trs.length), 5, 'the certificate lists the set points');
  ok('temperature model: the page shows its polynomials and set points as stored and links its certificate, which lists every a_d rounded to its U and the set points');
  await page.goto(`/ui/calibrations/${thermalTriad.id}`);
  assert.match(await page.textContent('h1'), /Triad temperature model of IMU-TC-3/);
  const elementRows = await page.$$eval('#thermal-polynomials tbody tr', (trs) => trs.map((tr) => [tr.querySelector('th').textContent, tr.querySelectorAll('td')[1].textContent]));
  assert.deepEqual(elementRows.map((r) => r[0]), ['b_x', 'b_y', 'b_z', 'S_xx', 'S_xy', 'S_xz', 'S_yx', 'S_yy', 'S_yz', 'S_zx', 'S_zy', 'S_zz'], 'one polynomial per element');
  close(num(elementRows[0][1]), thermalTriad.thermal.b[0].coefficients[0], 1e-3, 'a_0 of b_x on the page');
  const judged = await page.$$eval('#thermal-decision tbody tr', (trs) => trs.map((tr) => [tr.querySelector('th').textContent, tr.querySelector('td').textContent.trim()]));
  assert.deepEqual(judged, Object.entries(thermalTriad.decision.elements).map(([e, j]) => [e, j.worst.verdict]), 'the decision, element by element, as stored');
  const header = await page.request.get(`/ui/calibrations/${thermalTriad.id}/export/c`);
  assert.equal(header.status(), 200);
  assert.match(await header.text(), /ACCELCAL_B_POLY/);
  ok('triad temperature model: the page shows every element\'s polynomial and its type\'s decision as stored and offers the model\'s firmware files');
  // The same chamber campaign stored as five triads, one per set point,
  // then a model named from them.
  const campaign = JSON.parse(fs.readFileSync('examples/thermal-triad.json'));
  const setPoints = [...new Set(campaign.runs.map((r) => Math.round(r.temperature_c)))];
  const triadIds = [];
  for (const t of setPoints) {
    const runs = campaign.runs.filter((r) => Math.round(r.temperature_c) === t);
    const stored = await must(201, api('POST', '/v1/calibrations/triad', {
      body: JSON.stringify({ ...campaign, sensor_id: 'IMU-TC-5', runs }),
    }), `triad at ${t} °C`);
    triadIds.push(stored.id);
  }
  const named = await must(201, api('POST', '/v1/calibrations/thermal/triad', {
    body: JSON.stringify({ sensor_id: 'IMU-TC-5', calibrations: triadIds }),
  }), 'triad temperature model from stored triads');
  assert.deepEqual(named.thermal.b, (await must(200, api('POST', '/v1/identify/thermal/triad', {
    body: JSON.stringify({ ...campaign, sensor_id: 'IMU-TC-5' }),
  }), 'the campaign sent whole')).b, 'the same polynomials as the campaign sent whole');
  await page.goto(`/ui/calibrations/${named.id}`);
  const linked = await page.$$eval('dd a[href^="/ui/calibrations/"]', (as) => as.map((a) => a.getAttribute('href')));
  assert.deepEqual(linked, triadIds.map((id) => `/ui/calibrations/${id}`), 'the model links the triads it was fitted from');
  await Promise.all([page.waitForNavigation(), page.click(`a[href="/ui/calibrations/${triadIds[0]}"]`)]);
  const shown = (await page.textContent('main')).match(/Temperature\s*(-?\d+\.\d\d) °C/);
  assert.ok(shown, 'the triad states its temperature');
  const first = campaign.runs.filter((r) => Math.round(r.temperature_c) === setPoints[0]);
  close(Number(shown[1]), first.reduce((a, r) => a + r.temperature_c, 0) / first.length, 1e-3, 'the triad\'s temperature: its runs\' mean');
  ok('triad temperature model from five stored triads: the polynomials of the campaign sent whole; the page links each triad, whose page states its temperature');

  // ---------------------------------- accessibility and screenshots
  const pages = {
    fleet: '/ui/sensors',
    sensor: '/ui/sensors/SYN-001',
    calibration: `/ui/calibrations/${recal.id}`,
    certificate: `/ui/calibrations/${recal.id}/certificate`,
    triad: `/ui/calibrations/${triad.id}`,
    triadCertificate: `/ui/calibrations/${triad.id}/certificate`,
    triadSensor: '/ui/sensors/IMU-DEMO-1',
    thermal: `/ui/calibrations/${thermal.id}`,
    thermalCertificate: `/ui/calibrations/${thermal.id}/certificate`,
    thermalTriad: `/ui/calibrations/${thermalTriad.id}`,
    thermalTriadCertificate: `/ui/calibrations/${thermalTriad.id}/certificate`,
    thermalTriadNamed: `/ui/calibrations/${named.id}`,
    triadAtOneTemperature: `/ui/calibrations/${triadIds[0]}`,
  };
  const variants = {
    light: { viewport: { width: 1280, height: 900 }, colorScheme: 'light' },
    dark: { viewport: { width: 1280, height: 900 }, colorScheme: 'dark' },
    phone: { viewport: { width: 390, height: 844 }, deviceScaleFactor: 2, isMobile: true, hasTouch: true, colorScheme: 'light' },
  };
  const state = await context.storageState();
  for (const [variant, options] of Object.entries(variants)) {
    const ctx = await newContext({ ...options, storageState: state });
    const p = await ctx.newPage();
    for (const [name, url] of Object.entries(pages)) {
      const res = await p.goto(url);
      assert.equal(res.status(), 200, `${name} (${variant})`);
      if (variant !== 'phone') await axe(p, `${name} (${variant})`);
      // Measured against the screen's width: a phone zooms a page out to
      // fit content wider than its screen, and the window widens with it.
      const screenWidth = options.viewport.width;
      // Nothing laid out past the screen's edge, nor cut off by a box that
      // hides its overflow. A region that scrolls its own content sideways
      // may hold only a chart or a wide data table; tables shown as cards
      // (the fleet, a triad's matrices) fit the screen.
      const wide = await p.evaluate((width) => {
        const scrolls = (e) => ['auto', 'scroll'].includes(getComputedStyle(e).overflowX);
        const label = (e) => `${e.tagName.toLowerCase()}${e.id ? '#' + e.id : ''}${typeof e.className === 'string' && e.className ? '.' + e.className.trim().split(/\s+/).join('.') : ''}`;
        const certificate = document.body.classList.contains('certificate');
        const found = [];
        for (const e of document.body.querySelectorAll('*')) {
          if (e.closest('svg') && e.tagName.toLowerCase() !== 'svg') continue;
          let region = null;
          for (let a = e.parentElement; a && !region; a = a.parentElement) if (scrolls(a)) region = a;
          const r = e.getBoundingClientRect();
          // The innermost offenders: an element past the edge is named
          // only when none of its children is (they are the cause).
          const past = (x) => { const b = x.getBoundingClientRect(); return b.width > 0 && b.right > width + 1; };
          if (!region && past(e) && ![...e.children].some(past)) found.push(`${label(e)} ends at ${Math.round(r.right)}px`);
          if (['hidden', 'clip'].includes(getComputedStyle(e).overflowX) && e.scrollWidth > e.clientWidth + 1) found.push(`${label(e)} cuts off ${e.scrollWidth - e.clientWidth}px`);
          if (scrolls(e) && e.scrollWidth > e.clientWidth + 1) {
            const cards = e.querySelector('table.cards') && width < 600;
            // A certificate's tables fit an A4 page's width, as printed; on
            // a phone they scroll in their own labelled regions.
            const a4 = certificate && width >= 800;
            const allowed = !a4 && !cards && (e.querySelector('figure.chart svg, svg') || e.querySelector('table'));
            if (!allowed) found.push(`${label(e)} scrolls ${e.scrollWidth}px in ${e.clientWidth}px`);
          }
        }
        return found.slice(0, 8);
      }, screenWidth);
      assert.deepEqual(wide, [], `${name} (${variant}) at ${options.viewport.width}px`);
      const overflow = await p.evaluate(() => Math.max(document.documentElement.scrollWidth, window.innerWidth));
      assert.ok(overflow <= screenWidth + 1, `${name} (${variant}) is laid out ${overflow}px wide on a ${screenWidth}px screen`);
      // Chart labels stay legible at every width: their drawn size, the
      // SVG's font size scaled as the chart is, at least 10 CSS px.
      const smallest = await p.evaluate(() => Math.min(...[...document.querySelectorAll('figure.chart svg')].flatMap((svg) => {
        const scale = svg.getBoundingClientRect().width / svg.viewBox.baseVal.width;
        return [...svg.querySelectorAll('text')].map((t) => parseFloat(getComputedStyle(t).fontSize) * scale);
      })));
      assert.ok(!Number.isFinite(smallest) || smallest >= 10, `${name} (${variant}): chart labels drawn at ${smallest.toFixed(1)} px`);
      await p.screenshot({ path: path.join(SHOTS, `${name}-${variant}.png`), fullPage: true });
    }
    await ctx.close();
  }
  // The README's picture (docs/ui-sensor.jpg is a copy of this one).
  await page.goto('/ui/sensors/SYN-001');
  await page.screenshot({ path: path.join(SHOTS, 'readme.jpg'), type: 'jpeg', quality: 70 });
  ok('axe-core: no serious or critical violation, light and dark; no page wider than the screen, nothing cut off, only charts and wide data tables scrolling in their own regions (cards fit, and the certificate’s tables fit an A4 width), chart labels ≥ 10 px, at 1280 and 390 px; screenshots saved');

  // ------------------------------------------------------------ live
  // The sensor page and the fleet follow the event stream (issue 47 item
  // 5): what the API stores appears on a page already open, which swaps
  // its content without reloading (a mark left on the window survives).
  const liveCal = (i, id) => ({ ...synthetic(i), sensor_id: id });
  await must(201, api('POST', '/v1/calibrations', { body: JSON.stringify(liveCal(0, 'LIVE-001')) }), 'LIVE-001 first');
  await page.goto('/ui/sensors/LIVE-001');
  await page.waitForSelector('#live-status[data-state=open]', { state: 'attached' });
  await page.evaluate(() => { window.stillThisPage = true; });
  assert.equal(await page.$$eval('#chart-k0 circle.pt', (cs) => cs.length), 1);
  const later = await must(201, api('POST', '/v1/calibrations', { body: JSON.stringify(liveCal(1, 'LIVE-001')) }), 'LIVE-001 second');
  await page.waitForSelector(`#chart-k0 circle.pt[data-calibration-id="${later.id}"]`, { timeout: 20000 });
  assert.equal(await page.evaluate(() => window.stillThisPage), true, 'updated in place, not reloaded');
  assert.equal(await page.$$eval('#chart-k0 circle.pt', (cs) => cs.length), 2);
  assert.match(await page.textContent('#live-status'), /^Updated .* \(calibration\.stored\)\.$/);
  // Another sensor's events do not reach this page: events come in one
  // order, so once the third of this sensor's is shown, the other sensor's
  // (stored between them) would have come before it.
  await must(201, api('POST', '/v1/calibrations', { body: JSON.stringify(liveCal(2, 'LIVE-OTHER')) }), 'another sensor');
  const third = await must(201, api('POST', '/v1/calibrations', { body: JSON.stringify(liveCal(3, 'LIVE-001')) }), 'LIVE-001 third');
  await page.waitForSelector(`#chart-k0 circle.pt[data-calibration-id="${third.id}"]`, { timeout: 20000 });
  assert.equal(await page.$eval('#live-status', (p) => p.dataset.events), '2', 'two events of this sensor, none of the other');
  await page.goto('/ui/sensors');
  await page.waitForSelector('#live-status[data-state=open]', { state: 'attached' });
  await page.evaluate(() => { window.stillThisPage = true; });
  assert.equal(await page.locator('#fleet tr[data-sensor-id="LIVE-002"]').count(), 0);
  await must(201, api('POST', '/v1/calibrations', { body: JSON.stringify(liveCal(0, 'LIVE-002')) }), 'LIVE-002');
  await page.waitForSelector('#fleet tr[data-sensor-id="LIVE-002"]', { timeout: 20000 });
  assert.equal(await page.evaluate(() => window.stillThisPage), true, 'the fleet updated in place');
  await axe(page, 'fleet after a live update');
  // Without a session the pages' stream answers 204, which stops a
  // browser's EventSource for good (a redirect to the sign-in form would be
  // HTML, refused with a console error).
  const refused = await anonStream();
  assert.equal(refused.status, 204, 'the pages\' stream needs a session');
  assert.equal(refused.headers.get('cache-control'), 'no-store');
  ok('live: a calibration stored through the API appears on the open sensor page and the fleet without a reload; another sensor\'s event leaves the sensor page alone; the stream needs a session');

  // -------------------------------------------------------- refusals
  const anon = await newContext();
  const login = await anon.newPage();
  await login.goto('/ui/login');
  await login.fill('#token', 'acc_00000000000000000000000000000000_wrongwrongwrongwrongwrongwrongwrongwrongwro');
  provoked.add(`${BASE}/ui/login`);
  const [wrong] = await Promise.all([login.waitForNavigation(), login.click('button[type=submit]')]);
  assert.equal(wrong.status(), 401);
  assert.match(await login.textContent('[role=alert]'), /not accepted/);
  assert.equal(await login.locator('#token').count(), 1, 'the form again');
  ok('a wrong token gets the form again with the reason (401)');

  const forged = await anon.request.post('/ui/login', { form: { token: reader, csrf: 'guess', next: '/ui/sensors' }, maxRedirects: 0 });
  assert.equal(forged.status(), 403);
  await page.goto('/ui/sensors');
  const csrf = await page.$eval('form[action="/ui/logout"] input[name=csrf]', (i) => i.value);
  const noToken = await context.request.post('/ui/logout', { form: {}, maxRedirects: 0 });
  assert.equal(noToken.status(), 403);
  const wrongToken = await context.request.post('/ui/logout', { form: { csrf: 'x'.repeat(43) }, maxRedirects: 0 });
  assert.equal(wrongToken.status(), 403);
  const crossSite = await context.request.post('/ui/logout', { form: { csrf }, headers: { 'Sec-Fetch-Site': 'cross-site' }, maxRedirects: 0 });
  assert.equal(crossSite.status(), 403);
  assert.equal((await page.goto('/ui/sensors')).status(), 200, 'the session survives forged posts');
  ok('form posts without their CSRF token (or from another site) are refused with 403');

  const brief = await newContext();
  const bp = await brief.newPage();
  await signIn(bp, ADMIN, SHORT);
  assert.match(bp.url(), /\/ui\/sensors$/);
  await new Promise((r) => setTimeout(r, 2500));
  // The fleet's script stops following the stream once the session has
  // expired (the server ends the stream within a second; the browser's
  // reconnection is answered 204), with no error in the console.
  await bp.waitForSelector('#live-status[data-state=closed]', { state: 'attached', timeout: 20000 });
  assert.match(await bp.textContent('#live-status'), /^Live updates stopped; reload the page/);
  await bp.goto(`${SHORT}/ui/sensors`);
  assert.match(bp.url(), /\/ui\/login\?.*reason=expired/);
  assert.match(await bp.textContent('[role=alert]'), /expired/);
  ok('an expired session stops the page\'s live updates and goes back to sign-in, saying so');

  const doomed = (await must(201, api('POST', '/v1/tokens', { body: JSON.stringify({ role: 'reader' }) }), 'doomed token'));
  const rc = await newContext();
  const rp = await rc.newPage();
  await signIn(rp, doomed.token);
  // The fleet's event stream is open (had it connected after the
  // revocation, its own request would have ended the session first).
  await rp.waitForSelector('#live-status[data-state=open]', { state: 'attached' });
  await must(204, api('DELETE', `/v1/tokens/${doomed.id}`), 'revoke');
  await rp.waitForSelector('#live-status[data-state=closed]', { state: 'attached', timeout: 20000 });
  await rp.goto('/ui/sensors');
  assert.match(rp.url(), /reason=ended/);
  ok('revoking the token ends its sessions at once, and its open page\'s live updates');

  await Promise.all([page.waitForNavigation(), page.click('form[action="/ui/logout"] button')]);
  assert.match(page.url(), /\/ui\/login\?reason=signed-out/);
  await page.goto('/ui/sensors');
  assert.match(page.url(), /\/ui\/login/);
  ok('signing out ends the session');

  assert.deepEqual(offsite, [], 'no request leaves the server');
  assert.deepEqual(problems, [], 'no console error, page error or 5xx');
  ok('no request left localhost; no console error or warning, no page error, no 5xx');
} finally {
  await browser.close();
}
console.log(`ui: ${checks} checks passed`);
