// flashbrdf report.html, part 4: start-up and the keyboard.
"use strict";

function onKey(event) {
  const target = event.target;
  if (event.ctrlKey || event.metaKey || event.altKey) return;
  if (target && (target.tagName === "SELECT" || (target.tagName === "INPUT" && target.type === "text"))) return;
  if (rendersKey(event)) event.preventDefault();
}

document.addEventListener("keydown", onKey);
initRenders();
initBrdf();
materials();
