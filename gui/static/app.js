// texplorer operator pages: progressive enhancement only. Every form also works without this script;
// it adds the taxonomy picker, photo previews, the live level display while a step records, the busy
// state of a sent form, and takes a field's error away once the field is corrected.
"use strict";

function debounce(fn, ms) {
  let timer = null;
  return (...args) => {
    clearTimeout(timer);
    timer = setTimeout(() => fn(...args), ms);
  };
}

// -- taxonomy picker ---------------------------------------------------------------------------------

function setupLabel() {
  const input = document.getElementById("label");
  const out = document.getElementById("label-description");
  if (!input || !out) return null;
  const describe = debounce(async () => {
    const value = input.value.trim();
    if (!value) { out.textContent = ""; return; }
    let answer;
    try {
      const response = await fetch(`${input.dataset.describe}?label=${encodeURIComponent(value)}`);
      answer = await response.json();
    } catch (error) {
      return;  // the page is going away, or the server is: the server checks the label on submit anyway
    }
    out.textContent = answer.ok ? answer.description : answer.error;
    out.classList.toggle("bad", !answer.ok);
    if (answer.ok && input.value.trim() === value) clearError(input);
  }, 250);
  input.addEventListener("input", describe);
  return describe;
}

function setupPicker(describe) {
  const picker = document.getElementById("picker");
  if (!picker) return;
  const search = document.getElementById("picker-search");
  const results = document.getElementById("picker-results");
  const label = document.getElementById("label");
  const shape = document.getElementById("picker-p");
  const extra = document.getElementById("picker-x");
  let material = null;

  // The processing shape has no sensible default (the first, P1, would make polished granite natural): the
  // label stays empty until the operator chooses one. The extra attribute starts at X1, "no extra attribute".
  const compose = () => {
    if (!material) return;
    const out = document.getElementById("label-description");
    if (!shape.value) {
      label.value = "";
      if (out) { out.textContent = `${material}: now choose its processing shape (P)`; out.classList.remove("bad"); }
      return;
    }
    label.value = material + shape.value + extra.value;
    if (out) out.textContent = "";  // until the label's own description arrives
    if (describe) describe();
  };
  shape.addEventListener("change", compose);
  extra.addEventListener("change", compose);

  const show = (answer) => {
    results.replaceChildren();
    for (const m of answer.materials) {
      const item = document.createElement("li");
      const button = document.createElement("button");
      button.type = "button";
      const code = document.createElement("code");
      code.textContent = m.code;
      const name = document.createElement("span");
      name.textContent = m.name;
      const sub = document.createElement("span");
      sub.className = "sub";
      sub.textContent = ` (${m.subclass}, ${m.major})`;
      button.append(code, name, sub);
      if (m.simulation) {
        const physics = document.createElement("span");
        physics.className = `sub simulation ${m.simulation}`;
        physics.textContent = m.simulation === "hand-set"
          ? " · simulated with hand-set parameters" : " · simulated with parameters derived from its class";
        button.append(physics);
      }
      button.addEventListener("click", () => {
        material = m.code;
        compose();
        for (const other of results.querySelectorAll("button")) other.removeAttribute("aria-pressed");
        button.setAttribute("aria-pressed", "true");
        shape.focus();
      });
      item.append(button);
      results.append(item);
    }
    if (answer.total > answer.materials.length) {
      const more = document.createElement("li");
      more.className = "hint";
      more.textContent = `${answer.total - answer.materials.length} more: type more of the name or code.`;
      results.append(more);
    }
    if (!answer.total) {
      const none = document.createElement("li");
      none.className = "hint";
      none.textContent = "No material matches.";
      results.append(none);
    }
  };
  const query = debounce(async () => {
    const text = search.value.trim();
    if (!text) { results.replaceChildren(); return; }
    try {
      const response = await fetch(`${picker.dataset.search}?q=${encodeURIComponent(text)}`);
      show(await response.json());
    } catch (error) {
      results.replaceChildren();
    }
  }, 200);
  search.addEventListener("input", query);
  // Enter in the search box must not submit the start form.
  search.addEventListener("keydown", (event) => {
    if (event.key === "Enter") {
      event.preventDefault();
      const first = results.querySelector("button");
      if (first) first.focus();
    }
  });
}

// -- field errors: a corrected field loses its error ------------------------------------------------------
//
// The reason shown beside a field is about the value the server refused. Once the operator has changed it
// into a value the browser finds valid (required, pattern, maxlength; a photo file that is a PNG or JPEG;
// a choice picked; the label by the server's own check as it is typed, in setupLabel), the reason no
// longer describes the field and is taken away. The server checks every field again when the form is sent.

function clearError(field) {
  if (field.getAttribute("aria-invalid") !== "true") return;
  const described = (field.getAttribute("aria-describedby") || "").split(/\s+/).filter(Boolean);
  for (const id of described.filter((name) => name.endsWith("-error"))) {
    const reason = document.getElementById(id);
    if (reason) reason.remove();
  }
  const rest = described.filter((name) => !name.endsWith("-error"));
  if (rest.length) field.setAttribute("aria-describedby", rest.join(" "));
  else field.removeAttribute("aria-describedby");
  field.removeAttribute("aria-invalid");
  const box = field.closest(".invalid");
  if (box) box.classList.remove("invalid");
}

const PHOTO_HEADERS = [[0x89, 0x50, 0x4e, 0x47, 0x0d, 0x0a, 0x1a, 0x0a], [0xff, 0xd8, 0xff]];  // PNG, JPEG

async function isPhoto(file) {
  const head = new Uint8Array(await file.slice(0, 8).arrayBuffer());
  return PHOTO_HEADERS.some((magic) => magic.every((byte, i) => head[i] === byte));
}

async function corrected(field, refused) {
  if (field.tagName === "FIELDSET") return field.querySelector("input:checked") !== null;
  if (field.type === "file") return field.files.length === 1 && isPhoto(field.files[0]);
  return field.value !== refused && (!field.required || field.value.trim() !== "") && field.checkValidity();
}

function setupFieldErrors() {
  for (const field of document.querySelectorAll("[aria-invalid='true']")) {
    if (field.dataset.describe) continue;  // the label: the server's answer to what is typed decides
    const refused = field.value;
    const check = async () => {
      if (await corrected(field, refused)) clearError(field);
    };
    field.addEventListener("input", check);
    field.addEventListener("change", check);
  }
}

// -- photo previews ------------------------------------------------------------------------------------

function setupPreviews() {
  for (const input of document.querySelectorAll("input[type=file][data-preview]")) {
    const img = document.getElementById(input.dataset.preview);
    input.addEventListener("change", () => {
      const file = input.files && input.files[0];
      if (!file || !img) return;
      img.src = URL.createObjectURL(file);
      img.hidden = false;
      const placeholder = document.getElementById(input.dataset.placeholder);
      if (placeholder) placeholder.hidden = true;
      img.alt = `Preview of the chosen file ${file.name}`;
    });
  }
}

// -- live level while a step records ---------------------------------------------------------------------

function setupRecording() {
  const panel = document.getElementById("recording");
  if (!panel) return;
  const rest = panel.querySelector(".level-rest");
  const levelText = document.getElementById("level-value");
  const elapsed = document.getElementById("elapsed");
  const phase = document.getElementById("phase");
  const bar = panel.querySelector(".level-bar");
  const poll = async () => {
    let answer;
    try {
      const response = await fetch(panel.dataset.status, { cache: "no-store" });
      answer = await response.json();
    } catch (error) {
      phase.textContent = "Lost contact with the scanner program; retrying…";
      setTimeout(poll, 1000);
      return;
    }
    if (!answer.recording) {
      window.location.replace(answer.next || window.location.href);
      return;
    }
    const percent = Math.max(0, Math.min(100, 100 * answer.level));
    rest.style.width = `${100 - percent}%`;
    bar.setAttribute("aria-valuenow", percent.toFixed(0));
    levelText.textContent = answer.level_text;
    elapsed.textContent = answer.progress_text;
    phase.textContent = answer.phase_text;
    phase.classList.toggle("heating", Boolean(answer.heating));
    setTimeout(poll, 200);
  };
  poll();
}

// -- export job progress -----------------------------------------------------------------------------------

function setupExport() {
  const panel = document.getElementById("export");
  if (!panel) return;
  const phase = document.getElementById("export-phase");
  const bar = document.getElementById("export-progress");
  const count = document.getElementById("export-count");
  const error = document.getElementById("export-error");
  const download = document.getElementById("export-download");
  const cancel = document.getElementById("export-cancel");
  const again = document.getElementById("export-again");
  let started = false;
  const poll = async () => {
    let answer;
    try {
      const response = await fetch(panel.dataset.status, { cache: "no-store" });
      if (response.status === 404) {
        phase.textContent = "This export is gone (replaced by a newer one, or the server was restarted).";
        download.hidden = cancel.hidden = true;
        again.hidden = false;
        return;
      }
      answer = await response.json();
    } catch (failure) {
      phase.textContent = "Lost contact with the server; retrying…";
      setTimeout(poll, 1000);
      return;
    }
    bar.value = answer.fraction;
    bar.textContent = `${Math.round(100 * answer.fraction)} %`;
    phase.textContent = answer.phase_text;
    count.textContent = answer.count_text;
    error.textContent = answer.error;
    error.hidden = !answer.error;
    // Once the bundle is taken (the download below) or gone, a new export is what the page offers.
    download.hidden = !answer.ready;
    cancel.hidden = !(answer.running || answer.ready);
    again.hidden = answer.running || answer.ready;
    if (answer.ready && !started) {
      started = true;  // the download deletes the bundle on the server; the link stays for a failed start
      window.location.assign(answer.download);
    }
    if (answer.running || answer.ready) setTimeout(poll, answer.running ? 500 : 1000);
  };
  poll();
}

// -- busy state: a sent form says what it is doing and cannot be sent twice ------------------------------

function setupBusy() {
  const note = document.getElementById("busy-note");
  const forms = [...document.querySelectorAll("form")];
  for (const form of forms) {
    form.addEventListener("submit", (event) => {
      if (form.dataset.sending) {  // a second tap while the first is on its way
        event.preventDefault();
        return;
      }
      form.dataset.sending = "true";
      const submitter = event.submitter;
      const words = (submitter && submitter.dataset.busy) || form.dataset.busy || "Working…";
      // Disabled only after the event: a disabled submit button would leave its name and value out of
      // the request (the camera buttons say which photo to take that way).
      setTimeout(() => {
        for (const button of form.querySelectorAll("button")) button.disabled = true;
        if (submitter) {
          submitter.dataset.idle = submitter.textContent;
          submitter.textContent = words;
          submitter.classList.add("busy");
        }
        document.body.setAttribute("aria-busy", "true");
        if (note) {
          note.textContent = `${words} Please wait; the page changes by itself.`;
          note.hidden = false;
        }
      }, 0);
    });
  }
  // Back to a page kept by the browser: its forms can be sent again.
  window.addEventListener("pageshow", (event) => {
    if (!event.persisted) return;
    for (const form of forms) {
      delete form.dataset.sending;
      for (const button of form.querySelectorAll("button")) {
        button.disabled = false;
        button.classList.remove("busy");
        if (button.dataset.idle) button.textContent = button.dataset.idle;
      }
    }
    document.body.removeAttribute("aria-busy");
    if (note) note.hidden = true;
  });
}

document.addEventListener("DOMContentLoaded", () => {
  setupBusy();
  setupFieldErrors();
  setupPicker(setupLabel());
  setupPreviews();
  setupRecording();
  setupExport();
});
