/* Presets and the calibration editor: recording a preset here (preset_scale_cmd), loading a preset's
   zoom0.jpg, drawing the meter box and the needle's zero and full-scale points on it, and applying the
   calibration through calibration_control (the robot checks it by reading the picture itself). */
import { t } from './i18n.js';
import { boxQuad, needleAngle, selfCheckText } from './decode.js';
import { fetchPicture, listFolder, loadImage } from './files.js';
import { control, publish, subscribe } from './link.js';
import * as store from './state.js';
import { $, canvasPoint, log } from './ui.js';

const PRESETS_FOLDER = 'presets';
const calib = { preset: '', image: null, targets: [], box: null, zero: null, full: null, tool: null, drag: null,
  frame: 0 };

function calibMessage(text, failed) {
  $('calib-result').textContent = text;
  $('calib-result').className = failed ? 'error' : '';
}

function onPresetAck(msg) {
  const ok = msg.result === 'success';
  $('preset-result').textContent = t(ok ? 'recorded' : 'failed') + ': ' + msg.directory;
  $('preset-result').className = ok ? '' : 'error';
  log('preset_scale_ack #' + msg.trans_id + ' ' + msg.result + ': ' + msg.directory, !ok);
  if (ok) loadCalibration(msg.directory);   // the calibration editor opens the new recording
}

function loadCalibration(preset) {
  calib.preset = '';
  calib.image = null;
  calib.box = calib.zero = calib.full = null;
  calibMessage(t('loading {preset}…', { preset }));
  store.set('preset', null);
  return control('calibration_control', 'get', { preset }).then((text) => {
    const answer = JSON.parse(text);
    calib.targets = answer.targets;
    $('calib-preset').value = answer.preset;
    store.set('preset', { preset: answer.preset, targets: answer.targets });   // the limits panel's
    return fetchPicture(answer.preset + '/zoom0.jpg').then(loadImage).then((image) => {
      calib.image = image;
      calib.preset = answer.preset;
      const canvas = $('calib-picture');
      canvas.width = image.width;
      canvas.height = image.height;
      calibMessage(answer.preset + ': ' + (answer.calibrated ? t('{n} target(s) calibrated', { n: answer.targets.length })
        : t('not calibrated')) + ', ' + t('draft of {n} target(s)', { n: answer.draft.length }));
      drawCalib();
    });
  }).catch((err) => {
    calibMessage(t('cannot load {preset}', { preset }) + ': ' + err.message, true);
    drawCalib();   // no stale picture under a failed load
  });
}

function drawCalib() {
  if (!calib.frame) calib.frame = requestAnimationFrame(renderCalib);
}

function renderCalib() {
  calib.frame = 0;
  const canvas = $('calib-picture');
  const ctx = canvas.getContext('2d');
  canvas.classList.toggle('empty', !calib.image);
  if (!calib.image) return;
  ctx.drawImage(calib.image, 0, 0);
  ctx.lineWidth = 2;
  ctx.strokeStyle = '#00c853';   // the robot's calibrated targets
  for (const target of calib.targets) {
    const b = target.box;
    ctx.beginPath();
    for (let i = 0; i < 8; i += 2) ctx.lineTo(b[i], b[i + 1]);
    ctx.closePath();
    ctx.stroke();
  }
  const parts = [];
  if (calib.box) {
    const [x0, y0, x1, y1] = calib.box;
    ctx.strokeStyle = '#ff6d00';
    ctx.strokeRect(x0, y0, x1 - x0, y1 - y0);
    const c = [(x0 + x1) / 2, (y0 + y1) / 2];
    for (const [name, p, colour] of [['zero', calib.zero, '#2962ff'], ['full scale', calib.full, '#d50000']]) {
      if (!p) continue;
      ctx.strokeStyle = colour;
      ctx.beginPath();
      ctx.moveTo(c[0], c[1]);
      ctx.lineTo(p[0], p[1]);
      ctx.stroke();
      parts.push(t(name) + ' ' + needleAngle(calib.box, p).toFixed(1) + '°');
    }
    parts.unshift(t('box') + ' ' + Math.round(x1 - x0) + '×' + Math.round(y1 - y0) + ' px');
  }
  $('calib-geometry').textContent = parts.join(', ');
}

function setCalibTool(name) {
  calib.tool = calib.tool === name ? null : name;
  document.querySelectorAll('.calib-tool').forEach((b) => b.classList.toggle('active', b.id === 'calib-tool-' + calib.tool));
}

/** The recorded preset ids (folders of presets/) in the chooser. */
function listPresets() {
  listFolder(PRESETS_FOLDER).then((answer) => {
    const select = $('calib-choose');
    while (select.options.length > 1) select.remove(1);
    answer.entries.filter((e) => e.type === 'dir').forEach((e) => select.add(new Option(e.name, answer.path + '/' + e.name)));
  }).catch(() => {});
}

function chooseRecorded() {
  const folder = $('calib-choose').value;
  if (!folder) return;
  // The newest recording of that preset id (recordings are named YYYYMMDD_HHMMSS).
  listFolder(folder).then((answer) => {
    const dirs = answer.entries.filter((e) => e.type === 'dir');
    if (!dirs.length) throw new Error(t('no recording in {folder}', { folder }));
    return loadCalibration(folder + '/' + dirs[dirs.length - 1].name);
  }).catch((err) => calibMessage(err.message, true));
}

function applyCalibration(event) {
  event.preventDefault();
  if (!calib.preset) {
    calibMessage(t('load a preset first'), true);
    return;
  }
  if (!calib.box || calib.box[2] - calib.box[0] < 4 || calib.box[3] - calib.box[1] < 4) {
    calibMessage(t('draw the meter box on the picture first'), true);
    return;
  }
  const kind = $('calib-kind').value;
  const preset = calib.preset;
  const target = Number($('calib-target').value);
  const [x0, y0, x1, y1] = calib.box;
  const steps = [['mark_box', { box: boxQuad(calib.box) }], ['set_meter_type', { kind }]];
  if (kind === 'pointer') {
    if (!calib.zero || !calib.full) {
      calibMessage(t('click the needle\'s zero and full-scale points first'), true);
      return;
    }
    const angle = (p) => Math.round(needleAngle(calib.box, p) * 10) / 10;
    steps.push(['set_zero', { angle: angle(calib.zero), value: Number($('calib-zero-value').value) }],
      ['set_full_scale', { angle: angle(calib.full), value: Number($('calib-full-value').value) }],
      ['set_values', { values: { centre: [0.5, 0.5], aspect: Math.round((x1 - x0) / (y1 - y0) * 1000) / 1000 } }]);
  }
  const values = {};
  if ($('calib-name').value) values.name = $('calib-name').value;
  if ($('calib-unit').value && (kind === 'pointer' || kind === 'digital')) values.unit = $('calib-unit').value;
  if (kind === 'digital') {   // the robot learns the display from what it shows now
    if (!$('calib-expected').value.trim()) {
      calibMessage(t('type what the display shows now in "value shown now"'), true);
      return;
    }
    values.shown = $('calib-expected').value;
  }
  if (Object.keys(values).length) steps.push(['set_values', { values }]);
  calibMessage(t('applying…'));
  // One edit after the other, then apply: the first refusal stops the chain with the robot's text.
  steps.reduce((chain, [cmd, fields]) => chain.then(() => control('calibration_control', cmd,
    Object.assign({ preset, target }, fields))), Promise.resolve())
    .then((lastEdit) => {
      // the robot reads the picture itself; with the value the operator sees it refuses a wrong calibration
      const apply = { preset };
      const shown = $('calib-expected').value;
      if (shown !== '' && kind === 'pointer') {
        if (!Number.isFinite(Number(shown))) throw new Error(t('value shown now must be a number for a pointer'));
        apply.expected = JSON.parse(lastEdit).draft.map((_t, i) => (i === target ? Number(shown) : null));
      }
      if ($('calib-force').checked) apply.force = true;
      return control('calibration_control', 'apply', apply);
    })
    .then((text) => {
      const answer = JSON.parse(text);
      const checks = (answer.self_check || []).filter((c) => c.target === target).map(selfCheckText);
      calibMessage(t('applied') + ': ' + t('{n} target(s)', { n: answer.targets }) + ' (' + answer.kinds.map((k) => t(k)).join(', ') + ')' +
        (checks.length ? '; ' + checks.join('; ') : ''));
      return control('calibration_control', 'get', { preset }).then((got) => {
        calib.targets = JSON.parse(got).targets;
        store.set('preset', { preset, targets: calib.targets });
        drawCalib();
      });
    })
    .catch((err) => calibMessage(t('refused') + ': ' + err.message, true));
}

export function init() {
  window.consoleCalib = { ready: () => calib.image !== null && !$('calib-picture').classList.contains('empty'),
    preset: () => calib.preset,
    size: () => (calib.image ? [calib.image.width, calib.image.height] : null) };
  $('preset-form').addEventListener('submit', (event) => {
    event.preventDefault();
    publish('preset_scale_cmd', 'inspection_robot/PresetScaleCmd',
      { preset_id: $('preset-id').value, infrared: $('preset-infrared').checked, type: '', extra_data: '' });
    $('preset-result').textContent = t('recording…');
  });
  $('calib-tool-box').addEventListener('click', () => setCalibTool('box'));
  $('calib-tool-zero').addEventListener('click', () => setCalibTool('zero'));
  $('calib-tool-full').addEventListener('click', () => setCalibTool('full'));
  const canvas = $('calib-picture');
  canvas.addEventListener('pointerdown', (event) => {
    if (!calib.image) return;
    const p = canvasPoint(canvas, event);
    if (calib.tool === 'box') {
      calib.drag = p;
      calib.box = [p[0], p[1], p[0], p[1]];
      calib.zero = calib.full = null;   // angles are about the box centre: a new box needs new points
      canvas.setPointerCapture(event.pointerId);
    } else if ((calib.tool === 'zero' || calib.tool === 'full') && calib.box) {
      calib[calib.tool] = p;
    }
    drawCalib();
  });
  canvas.addEventListener('pointermove', (event) => {
    if (!calib.drag) return;
    const p = canvasPoint(canvas, event);
    const [ax, ay] = calib.drag;
    calib.box = [Math.min(ax, p[0]), Math.min(ay, p[1]), Math.max(ax, p[0]), Math.max(ay, p[1])];
    drawCalib();
  });
  canvas.addEventListener('pointerup', () => { calib.drag = null; });
  $('calib-load').addEventListener('click', () => loadCalibration($('calib-preset').value.trim()));
  $('calib-choose').addEventListener('focus', listPresets);
  $('calib-choose').addEventListener('change', chooseRecorded);
  $('calib-form').addEventListener('submit', applyCalibration);
  subscribe('preset_scale_ack', 'inspection_robot/PresetScaleAck', {}, onPresetAck);
}
