// The browser test (docs/web.md): Mainsail and Fluidd, unmodified, in headless Chromium against
// feedloopd on the simulated printer (virtual time: the 13-minute cube prints in seconds).
// For each UI, driven as a user drives it, with the mouse on the UI's own controls: the dashboard
// shows the printer ready; the G-code file is uploaded with the UI's upload button (the file
// chooser); a click on the file and on the dialog's or menu's Print starts it; the UI's pause and
// resume buttons pause and resume it, each state shown by the UI (the file position stays put
// while paused); temperatures, position and the part fan (M106 typed into the UI's console, which
// answers M115 there) are shown; the print completes; a second print is cancelled with the UI's
// cancel button (and its confirmation). The browser console must show no error but the 404s of
// Mainsail's optional theme files, which Moonraker answers the same way. Then feedloop's page must
// show the tracking-error plot and map of that print and the last calibration report (made
// first with `feedloop ident excite` + `feedloop ident fit`); screenshots are saved.
//
// usage: node webui_test.mjs FEEDLOOPD SOURCE_DIR OUT_DIR FEEDLOOP     exit 77: skipped (no chromium)
import { spawn, execFileSync } from 'node:child_process'
import fs from 'node:fs'
import os from 'node:os'
import path from 'node:path'

const [feedloopd, src, outDir, feedloopCli] = process.argv.slice(2)
const CHROMIUM = ['/usr/bin/chromium', '/usr/bin/chromium-browser'].find((p) => fs.existsSync(p))
if (!CHROMIUM) { console.log('SKIP: no chromium'); process.exit(77) }
let puppeteer
try { puppeteer = (await import('puppeteer-core')).default } catch { console.log('SKIP: run npm ci in tests/browser'); process.exit(77) }
const uplotDir = path.join(src, 'tests/browser/node_modules/uplot/dist')
const webui = path.join(src, '../shared/webui')
if (!fs.existsSync(path.join(webui, 'mainsail.tar.xz'))) { console.log('SKIP: no ../shared/webui'); process.exit(77) }
fs.mkdirSync(outDir, { recursive: true })

// The last calibration report for feedloop's page: `feedloop ident excite` records an X axis with
// a periodic position error, `feedloop ident fit` writes report.json; each daemon finds it in
// web.calibration_dir (${STATE_DIR}/ident) and the page must show it.
const reportDir = fs.mkdtempSync(path.join(os.tmpdir(), 'feedloop-ident-'))
let report = null
{
  const t0 = Date.now()
  try {
    execFileSync(feedloopCli, ['ident', 'excite', '--axis', 'x', '--out', path.join(reportDir, 'x.csv'), '--duration', '20',
      '--effect', 'periodic_position:period_mm=20,amplitude_um=15'], { stdio: 'inherit' })
    execFileSync(feedloopCli, ['ident', 'fit', '--trace', path.join(reportDir, 'x.csv'), '--out', path.join(reportDir, 'x-fit'), '--no-plots'],
      { stdio: 'inherit' })
    report = JSON.parse(fs.readFileSync(path.join(reportDir, 'x-fit', 'report.json'), 'utf8'))
    console.log(`calibration report made in ${((Date.now() - t0) / 1000).toFixed(1)} s: ${report.effects.map((e) => e.name).join(', ') || 'no effect'}`)
  } catch (e) {
    console.log(`feedloop ident failed: ${e.message}`)  // the page check below fails then
  }
}

const cube = path.join(src, '../shared/gcode/cube20_cartesian.gcode')

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

// Material Design icons as both UIs draw them (an <svg> path; Mainsail's panel buttons have no
// text, only the icon and a tooltip).
// The start of each path is enough (MDI releases differ in how they close the path).
const ICON = {
  pause: 'M14,19H18V5H14M6',
  play: 'M8,5.14V19.14L19,12.14L8,5.14Z',
  stop: 'M18,18H6V6H18V18Z',
  upload: 'M9,16V10H5L12,3L19,10H15V16H9M5,20V18H19V20H5Z',
  plus: 'M19,13H13V19H11V13H5V11H11V5H13V11H19V13Z',
}
const hasIcon = (c, icon) => c.icon.startsWith(icon)

// The visible clickable controls of the page: text, label (title, aria-label) and icon path.
// Each gets a data attribute so that the one chosen is clicked with the mouse, as a user would.
async function controls(page) {
  return page.evaluate(() => {
    const out = []
    let i = 0
    // The numbers of an earlier look are removed first: a control that is hidden now (a closed
    // menu's item stays in the page) must not keep a number that a visible one gets now (the
    // click went to the hidden "Upload Files" item of Fluidd's closed "+" menu, not to "Print").
    for (const e of document.querySelectorAll('[data-fl-ctl]')) delete e.dataset.flCtl
    for (const e of document.querySelectorAll('button, a, [role="button"], [role="menuitem"], .v-list-item--link')) {
      const r = e.getBoundingClientRect()
      const style = getComputedStyle(e)
      if (r.width === 0 || r.height === 0 || style.visibility === 'hidden' || style.display === 'none') continue
      // Disabled controls (Vuetify's list items are disabled by class and aria-disabled, and take
      // no pointer events: a click there lands on what lies beneath) are not offered.
      if (e.disabled || e.classList.contains('v-btn--disabled') || e.classList.contains('v-list-item--disabled') ||
          e.getAttribute('aria-disabled') === 'true') continue
      e.dataset.flCtl = String(++i)
      out.push({ id: i, text: (e.innerText || '').trim(), label: (e.getAttribute('title') || e.getAttribute('aria-label') || '').trim(),
        icon: e.querySelector('svg path')?.getAttribute('d') || '', href: e.getAttribute('href') || '' })
    }
    return out
  })
}

// The control `pred` picks, once it is there and has stopped moving (dialogs and menus open with
// a transition: a click in the middle of it lands beside the button).
// A mouse click on the element; where puppeteer finds no clickable point (a menu item inside
// Vuetify's transformed menu), the element's own click() (the click event its handler gets).
async function clickIt(page, handle) {
  try {
    await handle.click()
  } catch {
    await handle.evaluate((e) => e.click())
  }
}

async function waitForControl(page, what, pred, timeoutMs = 15000) {
  let seen = []
  const h = await waitFor(what, async () => {
    seen = await controls(page)
    let c = seen.find(pred)
    if (!c) return null
    const box = async (id) => (await page.$(`[data-fl-ctl="${id}"]`))?.boundingBox()
    const before = await box(c.id)
    await sleep(300)
    const after = await box(c.id)
    // (A menu item inside a transformed menu may have no box for puppeteer: clicked all the same.)
    if (before && after && (before.x !== after.x || before.y !== after.y || before.width !== after.width)) return null
    return page.$(`[data-fl-ctl="${c.id}"]`)
  }, timeoutMs)
  if (!h) console.log(`     controls seen: ${JSON.stringify(seen.map((c) => [c.text.slice(0, 30), c.label, c.icon.slice(0, 16), c.href]))}`)
  return h
}

async function gotoFiles(page, ui) {
  if (ui === 'fluidd') {
    await page.evaluate(() => { location.hash = '#/jobs' })
  } else {
    const link = await waitForControl(page, 'Mainsail: the G-Code Files link', (c) => c.href === '/files')
    if (link) await clickIt(page, link)
  }
  // The file list is there (and the dashboard's controls are gone).
  await waitFor(`${ui}: the file list`, async () => page.evaluate((ui) => {
    const t = document.body.innerText
    return ui === 'fluidd' ? location.hash === '#/jobs' && /\bJobs\b/.test(t) && /Name/.test(t) && !/Thermals/.test(t)
      : location.pathname === '/files' && /Current path/.test(t)
  }, ui))
}

async function gotoDashboard(page, ui) {
  if (ui === 'fluidd') {
    await page.evaluate(() => { location.hash = '#/' })
  } else {
    const link = await waitForControl(page, 'Mainsail: the Dashboard link', (c) => c.href === '/' && /dashboard/i.test(c.text))
    if (link) await clickIt(page, link)
  }
  await waitFor(`${ui}: the dashboard`, async () => page.evaluate((ui) => {
    const t = document.body.innerText
    return ui === 'fluidd' ? location.hash === '#/' && /Thermals/.test(t) : location.pathname === '/' && /Temperatures/.test(t)
  }, ui))
}

// Starts cube20.gcode from the UI's file list: a click on the file, then the dialog's
// print button.
async function startFromFiles(page, ui) {
  await gotoFiles(page, ui)
  const file = await waitFor(`${ui}: the file's row`, async () => {
    const rows = await page.$$('tbody tr')  // the file table (not the upload progress list)
    for (const r of rows) if (/cube20/.test(await r.evaluate((e) => e.innerText)) && await r.isVisible()) return r
    return null
  })
  if (!file) return
  // A click on the file's name (Fluidd opens its menu where the mouse is).
  const name = await file.evaluateHandle((r) => [...r.querySelectorAll('td')].find((td) => /cube20/.test(td.innerText)) || r)
  await name.asElement().click()
  const isPrint = (c) => /^print$/i.test(c.text) || /^print$/i.test(c.label)
  let print = await waitForControl(page, `${ui}: the dialog's or menu's print button`, isPrint, 5000)
  if (!print && ui === 'fluidd') {  // the menu by a right click, as Fluidd also offers it
    await name.asElement().click({ button: 'right' })
    print = await waitForControl(page, `${ui}: the context menu's print item`, isPrint, 5000)
  }
  if (print && process.env.FEEDLOOP_WEB_DEBUG) {
    console.log('     print control: ' + await print.evaluate((e) => {
      const r = e.getBoundingClientRect()
      const at = document.elementFromPoint(r.x + r.width / 2, r.y + r.height / 2)
      return `${e.tagName}.${e.className} box ${Math.round(r.x)},${Math.round(r.y)} ${Math.round(r.width)}x${Math.round(r.height)}; ` +
        `at its middle: ${at?.tagName}.${at?.className} (inside: ${e.contains(at)}) ${e.outerHTML.slice(0, 300)}`
    }))
  }
  if (print) await clickIt(page, print)
}

// A confirmation dialog after cancel (Fluidd always asks; Mainsail when configured to).
async function confirmIfAsked(page, ui) {
  const t0 = Date.now()
  while (Date.now() - t0 < 3000) {
    const c = (await controls(page)).find((c) => /^(yes|confirm|cancel print)$/i.test(c.text))
    if (c) {
      // The dialog opens with a transition: the button is clicked once it stands still (a click
      // while it grows lands beside it and closes the dialog unanswered).
      const h = await page.$(`[data-fl-ctl="${c.id}"]`)
      const before = await h?.boundingBox()
      await sleep(300)
      const after = await h?.boundingBox()
      if (!h || !before || !after || before.x !== after.x || before.y !== after.y || before.width !== after.width) continue
      console.log(`     ${ui}: confirming with "${c.text}"`)
      await clickIt(page, h)
      return
    }
    await sleep(200)
  }
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
  if (report) fs.cpSync(path.join(reportDir, 'x-fit'), path.join(tmp, 'ident', 'x-fit'), { recursive: true })
  const log = fs.openSync(path.join(outDir, `${ui}-feedloopd.log`), 'w')
  // FEEDLOOP_WEB_DEBUG=1: the daemon logs every API call the UI makes and its errors
  // (build/browser-test/<ui>-feedloopd.log).
  const debugArgs = process.env.FEEDLOOP_WEB_DEBUG ? ['--log-level', 'debug'] : []
  const daemon = spawn(feedloopd, ['--virtual-time', '--config', path.join(tmp, 'printer.yaml'), ...debugArgs],
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
    // In virtual time the simulated heaters report 0 °C until the first motion (docs/web.md, "Not done").
    check(startTemps.length >= 2 && startTemps.every((v) => v < 30), `${ui} shows temperatures below 30 °C at start: ${startTemps.join(', ')}`)

    // Upload with the UI's own upload button: the file chooser gets the G-code file, the UI
    // posts it (its multipart POST /server/files/upload) and lists it.
    // The whole 20 mm cube of ../shared/gcode (a 13-minute print: about 30 s in virtual time, time
    // enough to click pause, resume and cancel; the 3-layer example is over in a few seconds).
    const gcodePath = path.join(tmp, 'cube20.gcode')
    fs.copyFileSync(fs.existsSync(cube) ? cube : path.join(src, 'examples/gcode/cube20_3layers.gcode'), gcodePath)
    const gcodeSize = fs.statSync(gcodePath).size
    await gotoFiles(page, ui)
    // Mainsail: the files panel's upload button; Fluidd: its add (+) menu, "Upload Files".
    let uploadButton = null
    if (ui === 'fluidd') {
      const plus = await waitForControl(page, 'Fluidd: the file list\'s add (+) button', (c) => hasIcon(c, ICON.plus))
      if (plus) await clickIt(page, plus)
      uploadButton = await waitForControl(page, 'Fluidd: the "Upload Files" menu item', (c) => /^upload files$/i.test(c.text))
    } else {
      uploadButton = await waitForControl(page, 'Mainsail: the upload button', (c) => hasIcon(c, ICON.upload) || /upload/i.test(c.label))
    }
    if (uploadButton) {
      const [chooser] = await Promise.all([page.waitForFileChooser({ timeout: 10000 }), uploadButton.click()])
      await chooser.accept([gcodePath])
    }
    const listed = await waitFor(`upload through the UI: the daemon has the file's ${gcodeSize} bytes`, async () =>
      (await api('/server/files/list?root=gcodes')).find((f) => f.path === 'cube20.gcode' && f.size === gcodeSize))
    if (listed) await waitFor(`${ui} lists the uploaded file`, async () => /cube20\.gcode/.test(await text()))

    // Start: click the file, then the dialog's print button.
    await startFromFiles(page, ui)
    await gotoDashboard(page, ui)
    await waitFor(`${ui} shows Printing`, async () => /printing/i.test(await text()) && (await query('print_stats=state')).print_stats.state === 'printing')
    await page.screenshot({ path: path.join(outDir, `${ui}-printing.png`) })

    // Pause and resume with the UI's buttons.
    const pauseButton = await waitForControl(page, `${ui} pause button`, (c) => hasIcon(c, ICON.pause) || /^pause$/i.test(c.text))
    if (pauseButton) await clickIt(page, pauseButton)
    await waitFor(`${ui} shows Paused`, async () => /paused/i.test(await text()) && (await query('print_stats=state')).print_stats.state === 'paused')
    const pausedAt = (await query('virtual_sdcard=file_position')).virtual_sdcard.file_position
    await sleep(1500)
    const stillAt = (await query('virtual_sdcard=file_position')).virtual_sdcard.file_position
    check(pausedAt === stillAt && pausedAt > 0, `paused: the file position stays at ${pausedAt} (then ${stillAt})`)
    await page.screenshot({ path: path.join(outDir, `${ui}-paused.png`) })
    const resumeButton = await waitForControl(page, `${ui} resume button`, (c) => hasIcon(c, ICON.play) || /^resume$/i.test(c.text))
    if (resumeButton) await clickIt(page, resumeButton)
    // In virtual time the rest of the print can finish before the next look: the UI must have
    // left "Paused" and the job be printing or complete.
    await waitFor(`${ui} leaves Paused after resume`, async () => !/paused/i.test(await text()) &&
      ['printing', 'complete'].includes((await query('print_stats=state')).print_stats.state))

    // Temperatures and position as the UI shows them.
    await waitFor(`${ui} shows a hotend temperature above 100 °C`, async () => tempsOf(await text()).some((v) => v > 100 && v < 300), 60000)
    await waitFor(`${ui} shows a non-zero position`, async () =>
      [...(await text()).matchAll(/\[\s*(-?\d+\.\d+)\s*\]/g)].some((m) => Math.abs(Number(m[1])) > 0.5) ||
      (await query('toolhead=position')).toolhead.position.slice(0, 2).some((v) => Math.abs(v) > 0.5), 60000)

    // Console commands typed into the UI: M115 (a query: answered during the print) is answered
    // there; M106 S128, once the print is over (the job owns the print while it runs: a machine
    // command from another channel gets "busy", docs/jobs.md), sets the part fan, which the UI
    // then shows at 50 %.
    let consoleInput = null
    const typed = async (line) => {
      if (consoleInput && !(await consoleInput.evaluate((e) => e.isConnected))) consoleInput = null
      const input = consoleInput ?? await waitFor(`${ui} console input`, async () => {
        const all = await page.$$('textarea, input')
        for (const h of all) {
          const ph = await h.evaluate((e) => (e.placeholder || '') + ' ' + (e.labels?.[0]?.innerText || '') + ' ' + (e.getAttribute('aria-label') || ''))
          // Mainsail: "Send code..."; Fluidd's console page has one textarea, without a placeholder.
          const tag = await h.evaluate((e) => e.tagName)
          if ((/send code/i.test(ph) || (ui === 'fluidd' && tag === 'TEXTAREA')) && await h.isVisible()) return h
        }
        return null
      })
      if (!input) return
      consoleInput = input
      await input.click()
      await input.type(line)
      await page.keyboard.press('Enter')
    }
    if (ui === 'fluidd') await page.evaluate(() => { location.hash = '#/console' })
    await typed('M115')
    await waitFor(`${ui} console shows the answer to M115`, async () => /FIRMWARE_NAME:feedloop/.test(await text()))
    await gotoDashboard(page, ui)

    const done = await waitFor('the print completes (print_stats.state complete)', async () =>
      (await query('print_stats=state')).print_stats.state === 'complete', 300000)
    if (done) {
      await sleep(1500)
      fs.writeFileSync(path.join(outDir, `${ui}-complete.txt`), await text())
      // Mainsail's status panel says "Done"/"complete"; Fluidd's offers RE-PRINT at 100 %.
      await waitFor(`${ui} shows the print complete`, async () => {
        const t = await text()
        return ui === 'mainsail' ? /complete|done|finished/i.test(t) : /RE-PRINT/i.test(t) && /100\s*%/.test(t)
      })
      await page.screenshot({ path: path.join(outDir, `${ui}-complete.png`) })
    }
    if (ui === 'fluidd') await page.evaluate(() => { location.hash = '#/console' })
    await typed('M106 S128')
    await waitFor('M106 S128 from the UI\'s console sets fan.speed to 128/255',
      async () => Math.abs((await query('fan=speed')).fan.speed - 128 / 255) < 1e-3, 10000)
    await gotoDashboard(page, ui)
    // Both UIs show the part fan (Klipper's `fan`, speed 0..1) as a slider with its percentage in
    // an input field beside its name (Mainsail "Fan", Fluidd "Part Fan"): from the name, up to the
    // nearest element that holds a number field, whose value must be 50 (0.502 rounded).
    const fanShown = async () => page.evaluate(() => {
      const labels = [...document.querySelectorAll('body *')].filter((e) => /^(part )?fan$/i.test((e.innerText || '').trim()) &&
        ![...e.children].some((c) => /^(part )?fan$/i.test((c.innerText || '').trim())))
      const values = []
      for (const l of labels) {
        for (let e = l.parentElement, k = 0; e && k < 8; e = e.parentElement, ++k) {
          const input = [...e.querySelectorAll('input')].find((i) => i.type !== 'hidden' && i.value !== '' && !isNaN(Number(i.value)))
          if (input) { values.push(Number(input.value)); break }
        }
      }
      return values
    })
    const fanValues = await waitFor(`${ui} shows the part fan at 50 %`, async () => {
      const v = await fanShown()
      return v.some((x) => Math.abs(x - 50) <= 0.5) ? v : null
    }, 15000)
    if (!fanValues) console.log(`     fan fields found: ${JSON.stringify(await fanShown())}`)
    await page.screenshot({ path: path.join(outDir, `${ui}-fan.png`) })

    let hist = await api('/server/history/list?limit=5')
    check(hist.jobs[0]?.status === 'completed' && hist.jobs[0]?.filename === 'cube20.gcode' && hist.jobs[0]?.filament_used > 50,
      `history: the job is recorded as ${hist.jobs[0]?.status}, filament used ${hist.jobs[0]?.filament_used?.toFixed(1)} mm`)

    // A second print, cancelled with the UI's cancel button (and its confirmation, if it asks).
    // Mainsail offers cancel on a paused print (unless its "display cancel print" setting is on):
    // pause first, as its user does.
    await startFromFiles(page, ui)
    await gotoDashboard(page, ui)
    await waitFor(`${ui} shows Printing again`, async () => (await query('print_stats=state')).print_stats.state === 'printing' && /printing/i.test(await text()))
    if (ui === 'mainsail') {
      const pause2 = await waitForControl(page, `${ui} pause button`, (c) => hasIcon(c, ICON.pause))
      if (pause2) await clickIt(page, pause2)
      await waitFor(`${ui} shows Paused`, async () => /paused/i.test(await text()))
    }
    const cancelButton = await waitForControl(page, `${ui} cancel button`, (c) => hasIcon(c, ICON.stop) || /^cancel$/i.test(c.text))
    if (cancelButton) await clickIt(page, cancelButton)
    await confirmIfAsked(page, ui)
    await waitFor('the job is cancelled (print_stats.state cancelled)', async () => (await query('print_stats=state')).print_stats.state === 'cancelled', 60000)
    await waitFor(`${ui} shows Cancelled`, async () => /cancel+ed/i.test(await text()))
    await page.screenshot({ path: path.join(outDir, `${ui}-cancelled.png`) })
    hist = await api('/server/history/list?limit=5')
    check(hist.jobs[0]?.status === 'cancelled', `history: the second job is recorded as ${hist.jobs[0]?.status}`)

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
    // Beside the plots: the last calibration report, its effects and RMS figures as report.json says.
    const cal = await waitFor('feedloop page shows the last calibration report', async () =>
      own.evaluate(() => document.body.dataset.calibration === 'shown' ? document.getElementById('calibration').innerText : null))
    const rms = (v) => (typeof v === 'number' ? v.toFixed(2) : '?')
    check(report !== null && cal !== null && report.effects.every((e) => cal.includes(e.name)) &&
      cal.includes(`RMS ${rms(report.baseline.rms_um)} µm`) && cal.includes(`RMS ${rms(report.augmented.rms_um)} µm`),
      `feedloop page: calibration report shown (effects: ${report?.effects.map((e) => e.name).join(', ') || 'none'}; ` +
      `RMS ${rms(report?.baseline.rms_um)} -> ${rms(report?.augmented.rms_um)} µm)`)
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
// FEEDLOOP_WEBUI=fluidd runs one UI only (while working on it).
const uis = (process.env.FEEDLOOP_WEBUI || 'mainsail,fluidd').split(',')
if (uis.includes('mainsail')) await runUi('mainsail', basePort)
if (uis.includes('fluidd')) await runUi('fluidd', basePort + 1)
fs.rmSync(reportDir, { recursive: true, force: true })
console.log(failures.length ? `${failures.length} FAILED:\n  ${failures.join('\n  ')}` : 'all checks passed')
process.exit(failures.length ? 1 : 0)
