// The browser test (docs/web.md): Mainsail and Fluidd, unmodified, in headless Chromium against
// feedloopd on the simulated printer (virtual time: the 13-minute cube prints in seconds).
// For each UI: the dashboard loads and shows the printer ready; a file is uploaded (the UI's own
// multipart POST /server/files/upload from the page), started, paused, resumed and completes,
// each state shown by the UI; temperatures and the position shown by the UI change; a console
// command typed into the UI's console is answered there. The browser console must show no error
// but the 404s of Mainsail's optional theme files, which Moonraker answers the same way. Then
// feedloop's page must show the tracking-error plot and map of that print (screenshot saved).
//
// usage: node webui_test.mjs FEEDLOOPD SOURCE_DIR OUT_DIR     exit 77: skipped (no chromium)
import { spawn, execFileSync } from 'node:child_process'
import fs from 'node:fs'
import os from 'node:os'
import path from 'node:path'

const [feedloopd, src, outDir] = process.argv.slice(2)
const CHROMIUM = ['/usr/bin/chromium', '/usr/bin/chromium-browser'].find((p) => fs.existsSync(p))
if (!CHROMIUM) { console.log('SKIP: no chromium'); process.exit(77) }
let puppeteer
try { puppeteer = (await import('puppeteer-core')).default } catch { console.log('SKIP: run npm ci in tests/browser'); process.exit(77) }
const uplotDir = path.join(src, 'tests/browser/node_modules/uplot/dist')
const webui = path.join(src, '../shared/webui')
if (!fs.existsSync(path.join(webui, 'mainsail.tar.xz'))) { console.log('SKIP: no ../shared/webui'); process.exit(77) }
fs.mkdirSync(outDir, { recursive: true })

const sleep = (ms) => new Promise((r) => setTimeout(r, ms))
const failures = []
const check = (ok, what) => { console.log(`${ok ? 'ok  ' : 'FAIL'} ${what}`); if (!ok) failures.push(what) }

async function waitFor(what, fn, timeoutMs = 30000) {
  const t0 = Date.now()
  let last
  while (Date.now() - t0 < timeoutMs) {
    try { last = await fn(); if (last) { check(true, `${what} (${Date.now() - t0} ms)`); return last } } catch (e) { last = e.message }
    await sleep(250)
  }
  check(false, `${what}: not within ${timeoutMs} ms (last: ${String(last).slice(0, 200)})`)
  return null
}

async function runUi(ui, port) {
  console.log(`== ${ui}`)
  const tmp = fs.mkdtempSync(path.join(os.tmpdir(), `feedloop-${ui}-`))
  const uiDir = path.join(tmp, ui)
  fs.mkdirSync(uiDir)
  execFileSync('tar', ['-xJf', path.join(webui, `${ui}.tar.xz`), '-C', uiDir])
  const cfg = fs.readFileSync(path.join(src, 'config/examples/cartesian_sim_web.yaml'), 'utf8')
    .replace(/port: 7125/, `port: ${port}`)
    .replace(/ui_dir: .*/, `ui_dir: "${uiDir}"`)
    .replace(/page_dir: .*/, `page_dir: "${path.join(src, 'web/page')}"`)
    .replace(/uplot_dir: .*/, `uplot_dir: "${uplotDir}"`)
  fs.writeFileSync(path.join(tmp, 'printer.yaml'), cfg)
  const log = fs.openSync(path.join(outDir, `${ui}-feedloopd.log`), 'w')
  const daemon = spawn(feedloopd, ['--virtual-time', '--config', path.join(tmp, 'printer.yaml')],
    { env: { ...process.env, RUNTIME_DIRECTORY: tmp, STATE_DIRECTORY: tmp }, stdio: ['ignore', log, log] })
  const base = `http://127.0.0.1:${port}`
  await waitFor('feedloopd answers server.info', async () => (await fetch(`${base}/server/info`)).ok, 15000)
  const api = async (route, init) => (await (await fetch(base + route, init)).json()).result
  const query = async (q) => (await api(`/printer/objects/query?${q}`)).status

  const browser = await puppeteer.launch({ executablePath: CHROMIUM, headless: true, userDataDir: path.join(tmp, 'profile'),
    args: ['--no-sandbox', '--disable-gpu', '--disable-dev-shm-usage'], defaultViewport: { width: 1400, height: 1000 } })
  const page = await browser.newPage()
  const errors = []
  const notFound = []
  page.on('console', (m) => { if (m.type() === 'error') errors.push(`${m.text()} [${m.location()?.url ?? ''}]`) })
  page.on('pageerror', (e) => errors.push('uncaught: ' + e.message))
  page.on('response', (r) => { if (r.status() === 404) notFound.push(r.url()) })
  const text = () => page.evaluate(() => document.body.innerText)
  try {
    await page.goto(base + '/')
    if (ui === 'mainsail') await waitFor('Mainsail dashboard: printer ready (Standby, no "not ready")',
      async () => { const t = await text(); return /Standby/.test(t) && !/not ready|disconnected/i.test(t) })
    else await waitFor('Fluidd dashboard: printer ready', async () => { const t = await text(); return /READY/.test(t) && /Thermals/.test(t) })
    await page.screenshot({ path: path.join(outDir, `${ui}-ready.png`) })
    const tempsOf = (t) => [...t.matchAll(/(\d+(?:\.\d)?)\s*°C/g)].map((m) => Number(m[1]))
    const startTemps = tempsOf(await text())
    check(startTemps.length >= 2 && startTemps.every((v) => v < 30), `${ui} shows room temperatures at start: ${startTemps.join(', ')}`)

    // Upload, as the UIs do it (multipart, fields root and file), from the page.
    const gcode = fs.readFileSync(path.join(src, 'examples/gcode/cube20_3layers.gcode'), 'utf8')
    const up = await page.evaluate(async (body) => {
      const fd = new FormData()
      fd.append('root', 'gcodes')
      fd.append('file', new Blob([body]), 'cube20_3layers.gcode')
      const r = await fetch('/server/files/upload', { method: 'POST', body: fd })
      return { status: r.status, json: await r.json() }
    }, gcode)
    check(up.status === 201 && up.json.result.item.size === Buffer.byteLength(gcode), `upload: HTTP ${up.status}, size ${up.json.result?.item?.size}`)
    if (ui === 'fluidd') {
      await page.evaluate(() => { location.hash = '#/jobs' })
    }
    await waitFor(`${ui} lists the uploaded file`, async () => /cube20_3layers/.test(await text()))
    if (ui === 'fluidd') await page.evaluate(() => { location.hash = '#/' })

    // Start, pause, resume over the UI's own WebSocket API (JSON-RPC), as its buttons do:
    // Mainsail's run the PAUSE/RESUME macros, Fluidd's call printer.print.pause/resume.
    const rpc = (method, params) => page.evaluate(async (m, p) => {
      const ws = new WebSocket(`ws://${location.host}/websocket`)
      await new Promise((r, j) => { ws.onopen = r; ws.onerror = j })
      const reply = new Promise((r) => { ws.onmessage = (e) => { const d = JSON.parse(e.data); if (d.id === 7) r(d) } })
      ws.send(JSON.stringify({ jsonrpc: '2.0', method: m, params: p, id: 7 }))
      const d = await reply
      ws.close()
      return d
    }, method, params)
    const start = await rpc('printer.print.start', { filename: 'cube20_3layers.gcode' })
    check(start.result === 'ok', `printer.print.start: ${JSON.stringify(start)}`)
    await waitFor(`${ui} shows Printing`, async () => /printing/i.test(await text()))
    const pause = ui === 'mainsail' ? await rpc('printer.gcode.script', { script: 'PAUSE' }) : await rpc('printer.print.pause', {})
    check(pause.result === 'ok', `pause: ${JSON.stringify(pause)}`)
    await waitFor(`${ui} shows Paused`, async () => /paused/i.test(await text()))
    const pausedAt = (await query('virtual_sdcard=file_position')).virtual_sdcard.file_position
    await sleep(1500)
    const stillAt = (await query('virtual_sdcard=file_position')).virtual_sdcard.file_position
    check(pausedAt === stillAt && pausedAt > 0, `paused: the file position stays at ${pausedAt} (then ${stillAt})`)
    await page.screenshot({ path: path.join(outDir, `${ui}-paused.png`) })
    const resume = ui === 'mainsail' ? await rpc('printer.gcode.script', { script: 'RESUME' }) : await rpc('printer.print.resume', {})
    check(resume.result === 'ok', `resume: ${JSON.stringify(resume)}`)
    // In virtual time the rest of the print can finish before the next look: the UI must have
    // left "Paused" and the job be printing or complete.
    await waitFor(`${ui} leaves Paused after resume`, async () => !/paused/i.test(await text()) &&
      ['printing', 'complete'].includes((await query('print_stats=state')).print_stats.state))

    // Temperatures and position as the UI shows them.
    await waitFor(`${ui} shows a hotend temperature above 100 °C`, async () => tempsOf(await text()).some((v) => v > 100 && v < 300), 60000)
    await waitFor(`${ui} shows a non-zero position`, async () =>
      [...(await text()).matchAll(/\[\s*(-?\d+\.\d+)\s*\]/g)].some((m) => Math.abs(Number(m[1])) > 0.5), 60000)
    await page.screenshot({ path: path.join(outDir, `${ui}-printing.png`) })

    // A console command typed into the UI.
    if (ui === 'fluidd') await page.evaluate(() => { location.hash = '#/console' })
    const input = await waitFor(`${ui} console input`, async () => {
      const all = await page.$$('textarea, input')
      for (const h of all) {
        const ph = await h.evaluate((e) => (e.placeholder || '') + ' ' + (e.labels?.[0]?.innerText || '') + ' ' + (e.getAttribute('aria-label') || ''))
        // Mainsail: "Send code..."; Fluidd's console page has one textarea, without a placeholder.
        const tag = await h.evaluate((e) => e.tagName)
        if ((/send code/i.test(ph) || (ui === 'fluidd' && tag === 'TEXTAREA')) && await h.isVisible()) return h
      }
      return null
    })
    if (input) {
      await input.click()
      await input.type('M115')
      await page.keyboard.press('Enter')
      await waitFor(`${ui} console shows the answer to M115`, async () => /FIRMWARE_NAME:feedloop/.test(await text()))
    }
    if (ui === 'fluidd') await page.evaluate(() => { location.hash = '#/' })

    const done = await waitFor('the print completes (print_stats.state complete)', async () =>
      (await query('print_stats=state')).print_stats.state === 'complete', 180000)
    if (done) {
      await sleep(1500)
      fs.writeFileSync(path.join(outDir, `${ui}-complete.txt`), await text())
      // Mainsail's status panel says "Done"/"complete"; Fluidd's offers RE-PRINT at 100 %.
      await waitFor(`${ui} shows the print complete`, async () => {
        const t = await text()
        return ui === 'mainsail' ? /complete|done|finished/i.test(t) : /RE-PRINT/.test(t) && /100\s*%/.test(t)
      })
      await page.screenshot({ path: path.join(outDir, `${ui}-complete.png`) })
    }
    const hist = await api('/server/history/list?limit=5')
    check(hist.jobs[0]?.status === 'completed' && hist.jobs[0]?.filename === 'cube20_3layers.gcode',
      `history: the job is recorded as ${hist.jobs[0]?.status}`)

    // feedloop's page: the tracking-error plot and the map of this print.
    const own = await browser.newPage()
    own.on('response', (r) => { if (r.status() === 404) notFound.push(r.url()) })
    own.on('console', (m) => { if (m.type() === 'error') errors.push(`feedloop page: ${m.text()} [${m.location()?.url ?? ''}]`) })
    own.on('pageerror', (e) => errors.push('feedloop page uncaught: ' + e.message))
    await own.goto(base + '/server/feedloop/page/')
    const points = await waitFor('feedloop page has tracking-error points', async () => {
      const n = Number(await own.evaluate(() => document.body.dataset.points || 0))
      return n > 20 ? n : 0
    })
    const shape = await own.evaluate(() => ({
      canvases: document.querySelectorAll('.uplot canvas').length,
      layers: document.querySelectorAll('#layer option').length,
      rows: document.querySelectorAll('#layers tbody tr').length,
    }))
    check(shape.canvases >= 2 && shape.layers >= 3 && shape.rows === shape.layers,
      `feedloop page: ${shape.canvases} plots, ${shape.layers} layers in the map's list (${points} points)`)
    const tracking = (await query('feedloop_tracking')).feedloop_tracking
    check(tracking.error_max_mm > 0 && tracking.layers.length >= 3, `feedloop_tracking: max e_t ${(tracking.error_max_mm * 1000).toFixed(1)} um over ${tracking.layers.length} layers`)
    await own.screenshot({ path: path.join(outDir, `feedloop-page-${ui}.png`), fullPage: true })

    // Console errors: only the theme files' 404s that Moonraker gives too.
    const allowed404 = notFound.filter((u) => /\/server\/files\/config\/\.theme\//.test(u)).length
    const unexpected404 = notFound.filter((u) => !/\/server\/files\/config\/\.theme\//.test(u))
    // Fluidd always probes <host>:7125 as well (README of ../shared/webui); with the API on
    // another port that probe fails the same way against Moonraker.
    const probe = (e) => ui === 'fluidd' && port !== 7125 && /ws:\/\/127\.0\.0\.1:7125\/websocket' failed/.test(e)
    const other = errors.filter((e) => !/Failed to load resource: the server responded with a status of 404/.test(e) && !probe(e))
    const e404 = errors.filter((e) => /Failed to load resource: the server responded with a status of 404/.test(e)).length
    check(other.length === 0 && e404 <= allowed404 && unexpected404.length === 0,
      `${ui} browser console: ${other.length} errors (${other.slice(0, 3).join(' | ')}), ${e404} "404" errors (${errors.filter((e) => !other.includes(e)).join(' | ')}), 404s: ${notFound.join(', ') || 'none'}`)
  } finally {
    await browser.close()
    daemon.kill('SIGTERM')
    await new Promise((r) => daemon.on('exit', r))
    fs.rmSync(tmp, { recursive: true, force: true })
  }
}

const basePort = 17125 + (process.pid % 500) * 2
await runUi('mainsail', basePort)
await runUi('fluidd', basePort + 1)
console.log(failures.length ? `${failures.length} FAILED:\n  ${failures.join('\n  ')}` : 'all checks passed')
process.exit(failures.length ? 1 : 0)
