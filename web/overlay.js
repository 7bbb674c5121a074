// The panels of a bulletnet HTML replay (the tow panel for a tow, the mouth panel), kept in
// step with viser's playback bar. window.__BULLETNET__ (written by `bulletnet view --html`)
// holds:
//   time:   master sample times from the start of the replay [s], shape (K,)
//   panels: each with its title, its svg at frame 0 (bulletnet/viewer/panel.py draws it),
//           its fields, the [element id, attribute] pairs that change from frame to frame,
//           and its values: values[k][i] is fields[i] at frame k
// The first panel is open, the others folded (a click on a title opens or folds it).
(function () {
  "use strict";
  const data = window.__BULLETNET__;
  const box = document.createElement("div");
  box.id = "bulletnet-panel";
  box.innerHTML =
    '<div class="bulletnet-head"><b>bulletnet</b>' +
    '<span><button id="bulletnet-prev" title="previous frame">&#9664;</button>' +
    '<button id="bulletnet-next" title="next frame">&#9654;</button>' +
    '<button id="bulletnet-fold" title="hide or show the panels">&#8211;</button></span></div>' +
    '<div class="bulletnet-body">' +
    data.panels.map((panel, i) => "<details" + (i === 0 ? " open" : "") + "><summary>" +
                    panel.title + "</summary>" + panel.svg + "</details>").join("") +
    "</div>";
  document.body.appendChild(box);

  const elements = data.panels.map((panel) =>
    panel.fields.map(([id]) => document.getElementById(id)));
  let shown = 0;

  function frameAt(t) {  // last frame at or before t
    let lo = 0, hi = data.time.length - 1;
    while (lo < hi) {
      const mid = (lo + hi + 1) >> 1;
      if (data.time[mid] <= t + 1e-9) lo = mid; else hi = mid - 1;
    }
    return lo;
  }

  function draw(k) {
    data.panels.forEach((panel, p) => {
      const row = panel.values[k];
      panel.fields.forEach(([, attr], i) => {
        if (attr === "text") elements[p][i].textContent = row[i];
        else elements[p][i].setAttribute(attr, row[i]);
      });
    });
    shown = k;
  }

  function playbackSlider() {
    return document.querySelector('[role="slider"]');
  }

  function barHandler() {
    // The playback bar's own handler (viser's updateCurrentTime: jump to a time [s] and pause),
    // found on the bar's React component. A synthetic click on the bar cannot aim finer than a
    // whole pixel, and a time typed into its time field is rounded back to 0.1 s.
    const bar = document.querySelector(".mantine-Slider-root");
    const key = bar && Object.keys(bar).find((name) => name.startsWith("__reactFiber$"));
    for (let fiber = key && bar[key]; fiber; fiber = fiber.return) {
      const props = fiber.memoizedProps;
      if (props && typeof props.onChange === "function" && "max" in props) return props.onChange;
    }
    return null;
  }

  function step(by) {
    // One frame from the one the bar is at now. Playback may still add a few ms before the
    // pause takes effect, so the jump is made again once paused.
    const slider = playbackSlider();
    const jump = barHandler();
    if (!slider || !jump) return;
    const k = frameAt(parseFloat(slider.getAttribute("aria-valuenow"))) + by;
    const t = data.time[Math.max(0, Math.min(data.time.length - 1, k))];
    jump(t);
    setTimeout(() => jump(t), 100);
  }

  document.getElementById("bulletnet-prev").onclick = () => step(-1);
  document.getElementById("bulletnet-next").onclick = () => step(1);
  document.getElementById("bulletnet-fold").onclick = () => box.classList.toggle("folded");

  setInterval(() => {
    const slider = playbackSlider();
    if (!slider) return;
    const k = frameAt(parseFloat(slider.getAttribute("aria-valuenow")));
    if (k !== shown) draw(k);
  }, 40);
})();
