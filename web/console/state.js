/* The console's one store: what more than one panel reads, and the news panels give each other. A
   panel writes a value with set() or tells news with emit(); the panels that care subscribe with on().
   No panel calls another: the map redraws on 'status', the readings refresh on 'readings-changed', and
   so on. Keys are fixed (KEYS): a misspelt key throws instead of silently reaching no one. */

export const KEYS = {
  connected: 'the websocket is open (link.js)',
  status: 'the newest robot_status message (status.js)',
  task: 'the newest task_status, parsed (patrol.js)',
  'readings-changed': 'news: a review or an acknowledgement changed readings of this task id',
  'routines-changed': 'news: a routine was saved or deleted',
  'load-routine': 'news: the operator asked to load this saved routine into the planner',
  'submit-task': 'news: {cmd, data} a panel asks the patrol panel to send to task_control',
  preset: 'the preset open in the calibration editor: {preset, targets} as calibration_control get answers',
  'trend-meter': 'news: {target, unit} the operator asked to add this meter to the trend chart',
};

const values = { connected: false, status: null, task: null, preset: null };
const listeners = {};

function known(key) {
  if (!Object.prototype.hasOwnProperty.call(KEYS, key)) throw new Error('unknown store key ' + key);
}

/** The current value of ``key`` (null before anyone set it). */
export function get(key) {
  known(key);
  return key in values ? values[key] : null;
}

/** Set ``key`` and tell its listeners (in the order they subscribed); a listener's error is logged, not
    passed to the writer or the other listeners. */
export function set(key, value) {
  known(key);
  values[key] = value;
  emit(key, value);
}

/** Tell the listeners of ``key`` without keeping a value (news). */
export function emit(key, value) {
  known(key);
  for (const listener of listeners[key] || []) {
    try {
      listener(value);
    } catch (err) {
      console.error('store listener of ' + key + ': ' + err.message);
    }
  }
}

/** Call ``listener(value)`` whenever ``key`` is set or emitted; returns the function that unsubscribes. */
export function on(key, listener) {
  known(key);
  (listeners[key] = listeners[key] || []).push(listener);
  return () => { listeners[key] = listeners[key].filter((l) => l !== listener); };
}
