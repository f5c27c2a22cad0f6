// Keyboard for the review queue: every decision and every move without the
// mouse. The pages work without this script (links and a plain form).
(function () {
  "use strict";
  const $ = (s) => document.querySelector(s);
  const KEY = "postflight.reviewer";
  const name = $("#reviewer");
  if (name) {
    if (!name.value) name.value = localStorage.getItem(KEY) || "";
    name.addEventListener("input", () => localStorage.setItem(KEY, name.value.trim()));
  }
  const flash = (text) => {
    const f = $("#flash");
    f.textContent = text;
    f.classList.add("on");
    clearTimeout(flash.t);
    flash.t = setTimeout(() => f.classList.remove("on"), 3000);
  };
  const go = (url) => {
    if (url) location.href = url;
    else flash("No further candidate this way.");
  };
  const typing = (e) => ["INPUT", "TEXTAREA", "SELECT"].includes(e.target.tagName);

  // The queue: a selected row moved with j/k and opened with Enter.
  const rows = Array.from(document.querySelectorAll("tr.row"));
  let sel = 0;
  const select = (i) => {
    if (!rows.length) return;
    rows[sel].classList.remove("sel");
    sel = Math.max(0, Math.min(rows.length - 1, i));
    rows[sel].classList.add("sel");
    rows[sel].scrollIntoView({ block: "nearest" });
  };
  rows.forEach((r, i) => r.addEventListener("click", (e) => {
    if (e.target.tagName !== "A") { select(i); go(r.dataset.href); }
  }));
  select(0);

  // A candidate: supporting views stepped through with [ and ].
  const main = $("main.candidate");
  const form = $("#decision");
  const views = Array.from(document.querySelectorAll("#view-list li"));
  const img = $("#view");
  let view = img ? Number((img.getAttribute("src").match(/(\d+)$/) || [0, 0])[1]) : 0;
  const showView = (i) => {
    if (!views.length) return;
    view = (i + views.length) % views.length;
    img.src = views[view].dataset.src;
    $("#view-caption").textContent = views[view].dataset.caption;
  };
  ["prev", "next"].forEach((dir, k) => {
    const a = $("#view-" + dir);
    if (a) a.addEventListener("click", (e) => { e.preventDefault(); showView(view + (k ? 1 : -1)); });
  });

  let sent = false;
  const decide = (verdict, severity) => {
    if (sent) return;
    if (!name.value.trim()) {
      flash("Type your name as reviewer first, then press the key again.");
      name.focus();
      return;
    }
    if (severity) form.severity.value = String(severity);
    if (verdict !== "needs_repair") form.severity.value = "";
    sent = true;
    form.requestSubmit(form.querySelector('button[value="' + verdict + '"]'));
  };
  if (form) form.addEventListener("submit", () => { sent = true; });

  document.addEventListener("keydown", (e) => {
    if (e.key === "Escape") { if (typing(e)) e.target.blur(); return; }
    if (typing(e) || e.ctrlKey || e.metaKey || e.altKey) return;
    const k = e.key;
    let done = true;
    if (k === "i" && name) name.focus();
    else if (!main) {
      if (k === "j" || k === "ArrowDown") select(sel + 1);
      else if (k === "k" || k === "ArrowUp") select(sel - 1);
      else if (k === "Enter" || k === "o") go(rows.length && rows[sel].dataset.href);
      else done = false;
    } else if (k === "a") decide("accepted");
    else if (k === "r") decide("rejected");
    else if (k >= "1" && k <= "5") decide("needs_repair", Number(k));
    else if (k === "n") form.note.focus();
    else if (k === "j" || k === "ArrowRight") go(main.dataset.next);
    else if (k === "k" || k === "ArrowLeft") go(main.dataset.prev);
    else if (k === "]" || k === ".") showView(view + 1);
    else if (k === "[" || k === ",") showView(view - 1);
    else if (k === "q") go(main.dataset.queue);
    else done = false;
    if (done) e.preventDefault();
  });
  // Marks the page as listening (tests wait for it before pressing keys).
  document.body.dataset.keys = "ready";
})();
