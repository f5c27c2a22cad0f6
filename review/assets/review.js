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
    if (!["A", "BUTTON"].includes(e.target.tagName)) { select(i); go(r.dataset.href); }
  }));
  select(0);

  const needName = () => {
    if (name && name.value.trim()) return false;
    flash("Type your name as reviewer first, then press the key again.");
    if (name) name.focus();
    return true;
  };
  // The words of the severity scale, as the page states it.
  const SEVERITY = {};
  document.querySelectorAll("#severity-scale li").forEach((li) => {
    SEVERITY[li.value] = li.textContent.replace(/^\s*\d+\s*/, "").split(":")[0];
  });
  // Decide a queue row through the API (no page load): the row shows the
  // decision, the progress line the new counts, and the next row is selected.
  const pending = new Set();
  let progressSeq = 0;
  const decideRow = async (row, verdict, severity) => {
    if (!row || pending.has(row) || needName()) return;
    pending.add(row);
    const body = {
      version: Number(row.dataset.version), verdict: verdict,
      severity: severity || null, reviewer: name.value.trim(),
      // A state the reviewer set stays with the crack.
      condition: row.dataset.condition || null,
    };
    try {
      const r = await fetch("/api/candidates/" + encodeURIComponent(row.dataset.id) + "/decisions", {
        method: "POST", headers: { "Content-Type": "application/json" }, body: JSON.stringify(body),
      });
      const reply = await r.json().catch(() => ({}));
      if (r.status !== 201) { flash(reply.error || "The decision was refused (" + r.status + ")."); return; }
      row.dataset.version = String(reply.version);
      row.querySelector("form.quick input[name=version]").value = String(reply.version);
      const cell = row.querySelector("td.decision");
      const v = document.createElement("span");
      v.className = "v " + verdict;
      v.textContent = verdict === "needs_repair"
        ? "needs repair, severity " + severity + " (" + SEVERITY[severity] + ")"
        : verdict;
      const by = document.createElement("span");
      by.className = "sub";
      by.textContent = "by " + reply.reviewer;
      cell.replaceChildren(v, " ", by);
      // Progress as of the last request sent: sent after its decision was
      // stored, so the last one sent counts every decision stored before it.
      const seq = ++progressSeq;
      const q = await (await fetch("/api/candidates")).json();
      if (seq !== progressSeq) return;
      const p = q.progress;
      $("#reviewed").textContent = p.reviewed + " of " + p.total + " reviewed";
      const bar = $(".progress progress");
      if (bar) bar.value = p.reviewed;
      ["accepted", "needs_repair", "rejected"].forEach((k) => {
        const c = $("#count-" + k);
        if (c) c.textContent = String(p[k]);
      });
    } finally {
      pending.delete(row);
    }
  };
  // The row buttons fill in the reviewer (the plain form carries it).
  document.querySelectorAll("form.quick").forEach((f) => f.addEventListener("submit", (e) => {
    if (needName()) { e.preventDefault(); return; }
    f.reviewer.value = name.value.trim();
  }));

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
  // Zoom: the frame at its full size in a scrolling box; the box drawn or not.
  let boxed = true;
  const zoom = () => { const f = $("#frame"); if (f) f.classList.toggle("zoomed"); };
  const toggleBox = () => {
    if (!img) return;
    boxed = !boxed;
    views.forEach((li) => {
      li.dataset.src = li.dataset.src.replace(/\?box=0$/, "") + (boxed ? "" : "?box=0");
    });
    img.src = views[view].dataset.src;
    $("#box-toggle").textContent = boxed ? "hide box (b)" : "show box (b)";
  };
  if ($("#zoom")) $("#zoom").addEventListener("click", zoom);
  if ($("#box-toggle")) $("#box-toggle").addEventListener("click", toggleBox);
  if (img) img.addEventListener("click", zoom);

  let sent = false;
  const decide = (verdict, severity) => {
    if (sent || needName()) return;
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
      else if (k === "a" || k === "r" || (k >= "1" && k <= "5")) {
        const row = rows[sel];
        if (k === "a") decideRow(row, "accepted");
        else if (k === "r") decideRow(row, "rejected");
        else decideRow(row, "needs_repair", Number(k));
        select(sel + 1);
      } else done = false;
    } else if (k === "a") decide("accepted");
    else if (k === "r") decide("rejected");
    else if (k >= "1" && k <= "5") decide("needs_repair", Number(k));
    else if (k === "n") form.note.focus();
    else if (k === "j" || k === "ArrowRight") go(main.dataset.next);
    else if (k === "k" || k === "ArrowLeft") go(main.dataset.prev);
    else if (k === "]" || k === ".") showView(view + 1);
    else if (k === "[" || k === ",") showView(view - 1);
    else if (k === "q") go(main.dataset.queue);
    else if (k === "z") zoom();
    else if (k === "b") toggleBox();
    else done = false;
    if (done) e.preventDefault();
  });
  // Marks the page as listening (tests wait for it before pressing keys).
  document.body.dataset.keys = "ready";
})();
