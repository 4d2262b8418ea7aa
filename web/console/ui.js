/* The page's few shared helpers: element lookup, the Replies log, hold-to-act buttons, keyboard focus.
   Every panel imports them from here (there is no second copy). */

export const $ = (id) => document.getElementById(id);

const LOG_ROWS = 200;

/** One line in the Replies panel, newest first; ``failed`` shows it in red. */
export function log(text, failed) {
  const item = document.createElement('li');
  item.textContent = new Date().toLocaleTimeString() + '  ' + text;
  if (failed) item.className = 'failed';
  const list = $('log');
  list.insertBefore(item, list.firstChild);
  while (list.children.length > LOG_ROWS) list.removeChild(list.lastChild);
}

/** Whether a key event goes to a text field (then it is typing, not driving). */
export function typing(event) {
  return /^(INPUT|TEXTAREA|SELECT)$/.test(event.target.tagName) && event.target.type !== 'range';
}

/** ``press`` while the pointer holds ``button``, ``release`` when it lets go or is lost. */
export function holdButton(button, press, release) {
  button.addEventListener('pointerdown', (event) => {
    button.setPointerCapture(event.pointerId);
    press();
  });
  for (const type of ['pointerup', 'pointercancel', 'lostpointercapture']) button.addEventListener(type, release);
}

/** A canvas point of a pointer event, in the canvas's own pixels (it may be drawn scaled). */
export function canvasPoint(canvas, event) {
  const rect = canvas.getBoundingClientRect();
  return [(event.clientX - rect.left) * canvas.width / rect.width, (event.clientY - rect.top) * canvas.height / rect.height];
}

/** ``run`` (a function returning a promise) made safe to call on every status: one run in flight,
    and one more after it when it was asked for meanwhile, never a pile of them. */
export function coalesced(run) {
  const state = { running: false, again: false };
  const go = () => {
    if (state.running) {
      state.again = true;
      return;
    }
    state.running = true;
    run().catch(() => {}).then(() => {
      state.running = false;
      if (state.again) {
        state.again = false;
        go();
      }
    });
  };
  return go;
}

/** An empty table's one row saying so, across its ``columns``; returns the cell (a caller may style it). */
export function emptyRow(body, columns, text) {
  const cell = body.insertRow().insertCell();
  cell.colSpan = columns;
  cell.textContent = text;
  return cell;
}
