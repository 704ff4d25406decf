// Drive viewer.html in headless Chromium through playwright-core (no browser download: the system's chromium).
//
//   node drive.js < plan.json > result.json
//
// plan: {"chromium": PATH, "profile": EMPTY_FOLDER, "width": W, "height": H,
//        "cases": [{"name": N, "url": VIEWER_PAGE_URL, "views": [{"x", "y", "width", "height", "shot": PNG_PATH}]}]}
// result: {"cases": [{"name", "console": [...], "pageErrors": [...], "failedRequests": [...], "badResponses": [...],
//                     "osdEvents": [...], "error": null | MESSAGE, "views": [showLevel's answer + "shot"]}]}
// One browser and one page for every case (the launch is most of the time). A case that throws records
// its error and the others still run; the exit status is 0 unless the browser itself could not run.
"use strict";
const {chromium} = require("playwright-core");

const ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
  "--disable-background-networking", "--disable-component-update", "--disable-sync",
  "--force-color-profile=srgb", "--hide-scrollbars"];

// One page for every case (a new page costs as much as the rest of a case): the listeners write into the case
// being shown.
function listen(page, state) {
  page.on("console", (m) => {
    if (m.type() === "error" || m.type() === "warning") state.out.console.push(`${m.type()}: ${m.text()}`);
  });
  page.on("pageerror", (e) => state.out.pageErrors.push(String(e)));
  page.on("requestfailed", (r) => state.out.failedRequests.push(`${r.url()}: ${r.failure() && r.failure().errorText}`));
  page.on("response", (r) => { if (r.status() >= 400) state.out.badResponses.push(`${r.status()} ${r.url()}`); });
}

async function runCase(page, state, c) {
  const out = state.out = {name: c.name, console: [], pageErrors: [], failedRequests: [], badResponses: [],
    osdEvents: [], error: null, views: []};
  try {
    await page.goto(c.url, {waitUntil: "load"});
    await page.evaluate(() => window.osdReady.then(() => true));
    for (const v of c.views) {
      const drawn = await page.evaluate((v) => window.showLevel(v.x, v.y, v.width, v.height), v);
      await page.locator("#viewer").screenshot({path: v.shot, animations: "disabled"});
      out.views.push({...drawn, shot: v.shot});
    }
    out.osdEvents = await page.evaluate(() => window.osdEvents);
  } catch (e) {
    out.error = String(e && e.message || e);
  }
  return out;
}

async function main() {
  const plan = JSON.parse(require("fs").readFileSync(0, "utf8"));
  const context = await chromium.launchPersistentContext(plan.profile, {
    executablePath: plan.chromium, args: ARGS, headless: true,
    viewport: {width: plan.width, height: plan.height}, deviceScaleFactor: 1,
  });
  const cases = [];
  try {
    // nothing leaves the machine: a request for another host is aborted (and recorded as failed)
    await context.route((url) => url.hostname !== "127.0.0.1", (route) => route.abort("blockedbyclient"));
    const page = context.pages()[0] || await context.newPage();
    const state = {out: null};
    listen(page, state);
    for (const c of plan.cases) cases.push(await runCase(page, state, c));
  } finally {
    await context.close();
  }
  process.stdout.write(JSON.stringify({cases}));
}

main().catch((e) => { process.stderr.write(String(e && e.stack || e) + "\n"); process.exit(1); });
