/* The patrol planner panel: presets (and the meters they read) picked from a searchable list or by
   clicking their stop on the map, grouped into stops (planning.js); "plan route" asks task_manager
   for the order and the path (task_control plan) and draws it on the map; "start patrol" submits the
   task; "save as routine" stores it under a name for the schedules. */
import { t } from './i18n.js';
import { listFolder } from './files.js';
import { control, subscribe } from './link.js';
import { addLayer, addTool, drawMap } from './map.js';
import * as store from './state.js';
import { addPresets, buildTask, catalogEntry, entriesAt, removePreset, routeText, routineName, searchCatalog,
  stopsOfTask, taskId } from './planning.js';
import { $ } from './ui.js';

const PRESETS_FOLDER = 'presets';
const LOAD_PARALLEL = 4;    // calibration_control gets in flight while the list loads
const LIST_SHOWN = 100;     // catalog rows shown at once (the search narrows it)
// Told to the schedules panel (which lists the routines) when one is saved.
const planner = { catalog: [], loading: null, asked: false, stops: [], route: null, drawn: null };

/** Every preset id's newest recording with its stop pose and meters (file_control list, then
    calibration_control get of each, a few at a time). */
function loadCatalog() {
  if (planner.loading) return planner.loading;
  planner.asked = true;
  $('planner-catalog-info').textContent = t('loading the preset list…');
  planner.loading = listFolder(PRESETS_FOLDER).then((answer) => {
    const ids = answer.entries.filter((e) => e.type === 'dir').map((e) => e.name);
    const entries = [];
    const failures = [];
    let next = 0;
    const worker = () => {
      if (next >= ids.length) return Promise.resolve();
      const id = ids[next++];
      return listFolder(PRESETS_FOLDER + '/' + id).then((folder) => {
        const recordings = folder.entries.filter((e) => e.type === 'dir').map((e) => e.name).sort();
        if (!recordings.length) throw new Error('no recording');
        const directory = PRESETS_FOLDER + '/' + id + '/' + recordings[recordings.length - 1];
        return control('calibration_control', 'get', { preset: directory }, true);
      }).then((text) => entries.push(catalogEntry(id, JSON.parse(text))))
        .catch((err) => failures.push(id + ': ' + err.message))
        .then(worker);
    };
    return Promise.all(Array.from({ length: LOAD_PARALLEL }, worker)).then(() => {
      planner.catalog = entries;
      const calibrated = entries.filter((e) => e.calibrated).length;
      $('planner-catalog-info').textContent = t('{n} preset(s), {calibrated} calibrated', { n: entries.length,
        calibrated }) + (failures.length ? '; ' + t('not listed') + ': ' + failures.join('; ') : '');
      renderCatalog();
      drawMap();
    });
  }).catch((err) => {
    $('planner-catalog-info').textContent = t('preset list refused') + ': ' + err.message;
  }).then(() => { planner.loading = null; });
  return planner.loading;
}

function renderCatalog() {
  const list = $('planner-catalog');
  const found = searchCatalog(planner.catalog, $('planner-search').value);
  list.textContent = '';
  for (const entry of found.slice(0, LIST_SHOWN)) {
    const item = document.createElement('li');
    item.dataset.preset = entry.directory;
    const add = document.createElement('button');
    add.type = 'button';
    add.className = 'planner-add';
    add.textContent = t('add');
    add.disabled = !entry.calibrated || !entry.pose;
    add.addEventListener('click', () => pick([entry]));
    const name = document.createElement('b');
    name.textContent = entry.id;
    const meters = document.createElement('span');
    meters.className = 'meters';
    meters.textContent = (entry.calibrated ? entry.meters.join(', ') || t('no named meter') : t('not calibrated'))
      + (entry.pose ? ' · (' + entry.pose.x.toFixed(1) + ', ' + entry.pose.y.toFixed(1) + ')' : '');
    item.className = add.disabled ? 'disabled' : '';
    item.append(add, name, meters);
    list.appendChild(item);
  }
  if (found.length > LIST_SHOWN) {
    const more = document.createElement('li');
    more.textContent = t('{n} more: narrow the search', { n: found.length - LIST_SHOWN });
    list.appendChild(more);
  }
}

function setStops(stops, message) {
  planner.stops = stops;
  planner.route = null;   // the stops changed: the drawn route no longer holds
  routeMessage(message || '');
  renderStops();
  drawMap();
}

function pick(entries) {
  const result = addPresets(planner.stops, entries);
  setStops(result.stops, result.skipped.length ? t('not added') + ': ' + result.skipped.join('; ') : '');
}

function routeMessage(text, failed) {
  $('planner-route').textContent = text;
  $('planner-route').className = failed ? 'error' : '';
}

function renderStops() {
  const list = $('planner-stops');
  list.textContent = '';
  const presets = planner.stops.reduce((n, s) => n + s.presets.length, 0);
  $('planner-count').textContent = planner.stops.length ? '(' + t('{stops} stop(s), {presets} preset(s)',
    { stops: planner.stops.length, presets }) + ')' : '';
  for (const stop of planner.stops) {
    const item = document.createElement('li');
    item.dataset.stop = stop.name;
    const title = document.createElement('b');
    title.textContent = stop.name + ' (' + stop.pose.x.toFixed(1) + ', ' + stop.pose.y.toFixed(1) + '): ';
    item.appendChild(title);
    for (const directory of stop.presets) {
      const part = document.createElement('span');
      part.className = 'preset';
      part.textContent = directory.split('/').slice(-2, -1)[0] || directory;
      part.title = directory;
      const remove = document.createElement('button');
      remove.type = 'button';
      remove.textContent = '×';
      remove.title = t('remove {preset}', { preset: directory });
      remove.addEventListener('click', () => setStops(removePreset(planner.stops, directory)));
      part.appendChild(remove);
      item.appendChild(part);
    }
    list.appendChild(item);
  }
}

function task(id) {
  return buildTask(planner.stops, { id, order: $('planner-order').value, retries: $('planner-retries').value });
}

function planRoute() {
  let data;
  try {
    data = task(null);
  } catch (err) {
    routeMessage(err.message, true);
    return;
  }
  routeMessage(t('planning…'));
  const asked = planner.stops;
  control('task_control', 'plan', data).then((text) => {
    if (planner.stops !== asked) return;   // changed meanwhile: that answer is not this plan's
    planner.route = JSON.parse(text);
    routeMessage(routeText(planner.route));
    drawMap();
  }).catch((err) => routeMessage(t('plan refused') + ': ' + err.message, true));
}

function startPatrol() {
  let data;
  try {
    data = task(taskId(new Date()));
  } catch (err) {
    routeMessage(err.message, true);
    return;
  }
  store.emit('submit-task', { cmd: 'submit', data: JSON.stringify(data) });
}

function saveRoutine() {
  let data;
  try {
    data = { name: routineName($('routine-name').value.trim()), task: task(null) };
  } catch (err) {
    routeMessage(err.message, true);
    return;
  }
  control('task_control', 'routine_save', data).then(() => {
    routeMessage(t('routine {name} saved', { name: data.name }));
    store.emit('routines-changed');
  }).catch((err) => routeMessage(t('routine refused') + ': ' + err.message, true));
}

/** A saved routine's stops into the planner (news from the schedules panel). */
function loadRoutine(routine) {
  setStops(stopsOfTask(routine.task), t('routine {name} loaded', { name: routine.name }));
  $('routine-name').value = routine.name;
  if (routine.task.order) $('planner-order').value = routine.task.order;
  if (routine.task.retries !== undefined) $('planner-retries').value = routine.task.retries;
}

/** On the map: the catalog's stop poses (grey squares), the picked stops (numbered), the planned route. */
function drawLayer(ctx, toScreen) {
  ctx.fillStyle = '#546e7a';
  for (const entry of planner.catalog) {
    if (!entry.pose || !entry.calibrated) continue;
    const [sx, sy] = toScreen([entry.pose.x, entry.pose.y]);
    ctx.fillRect(sx - 3, sy - 3, 6, 6);
  }
  const route = planner.route;
  planner.drawn = route;
  if (route && route.path.length) {
    ctx.strokeStyle = '#6a1b9a';
    ctx.lineWidth = 3;
    ctx.beginPath();
    route.path.forEach((p, i) => {
      const [sx, sy] = toScreen(p);
      if (i) ctx.lineTo(sx, sy); else ctx.moveTo(sx, sy);
    });
    ctx.stroke();
  }
  const stops = route ? route.stops : planner.stops;
  ctx.font = 'bold 11px sans-serif';
  ctx.textAlign = 'center';
  ctx.textBaseline = 'middle';
  stops.forEach((stop, i) => {
    const [sx, sy] = toScreen([stop.pose.x, stop.pose.y]);
    ctx.fillStyle = route ? '#6a1b9a' : '#1565c0';
    ctx.beginPath();
    ctx.arc(sx, sy, 8, 0, 2 * Math.PI);
    ctx.fill();
    ctx.fillStyle = '#fff';
    ctx.fillText(String(i + 1), sx, sy);
  });
  ctx.textAlign = 'start';
  ctx.textBaseline = 'alphabetic';
}

export function init() {
  // For the browser tests: what the planner holds.
  window.consolePlanner = { catalog: () => planner.catalog.length, stops: () => planner.stops,
    route: () => planner.route, loading: () => planner.loading !== null,
    routeDrawn: () => planner.route !== null && planner.drawn === planner.route };
  $('planner-search').addEventListener('input', renderCatalog);
  $('planner-search').addEventListener('focus', () => { if (!planner.catalog.length) loadCatalog(); });
  $('planner-refresh').addEventListener('click', loadCatalog);
  const togglePick = addTool('pick', (world, tolerance) => {
    const entries = entriesAt(planner.catalog, world, tolerance);
    if (entries.length) pick(entries);
    else routeMessage(t('no calibrated preset recorded there (grey squares mark them)'), true);
  });
  $('tool-pick').addEventListener('click', () => {
    if (!planner.catalog.length) loadCatalog();
    togglePick();
  });
  $('planner-plan').addEventListener('click', planRoute);
  store.on('load-routine', loadRoutine);
  $('planner-start').addEventListener('click', startPatrol);
  $('planner-clear').addEventListener('click', () => setStops([]));
  $('routine-save').addEventListener('click', saveRoutine);
  ['planner-order', 'planner-retries'].forEach((id) => $(id).addEventListener('change', () => {
    if (planner.route) setStops(planner.stops);   // another order: plan again
  }));
  addLayer(drawLayer);
  // The first task_status comes once the link is up (and authenticated): then load the list.
  subscribe('task_status', 'inspection_robot/GeneralTopic', { queue_length: 1 }, () => {
    if (!planner.asked) loadCatalog();
  });
}
