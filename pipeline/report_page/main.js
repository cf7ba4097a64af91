// flashbrdf report.html, part 4: start-up and the keyboard.
"use strict";

function onKey(event) {
  const target = event.target;
  if (event.ctrlKey || event.metaKey || event.altKey) return;
  if (target && (target.tagName === "SELECT" || (target.tagName === "INPUT" && target.type === "text"))) return;
  if (rendersKey(event)) event.preventDefault();
}

// The sticky toolbar sits under the header, whose height changes as it wraps.
function trackHeaderHeight() {
  const header = document.querySelector("header.top");
  const set = () => document.documentElement.style.setProperty("--header-h", `${header.offsetHeight}px`);
  set();
  if (window.ResizeObserver) new ResizeObserver(set).observe(header);
}

trackHeaderHeight();
document.addEventListener("keydown", onKey);
initRenders();
initBrdf();
materials();
