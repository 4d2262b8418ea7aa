/* Limits of the preset open in the calibration editor (store key 'preset'): per meter its normal band
   and the alarm band around it (between them a warning), per lamp or switch its expected state. Saved
   with calibration_control upload of the preset's targets as get answered them, the limits changed:
   one request, checked by the robot like every calibration; a refusal shows the robot's reason. */
import { t, unitText } from './i18n.js';
import { limitFields, limitKeys, stateChoices, statesKind, withLimits } from './bands.js';
import { control } from './link.js';
import * as store from './state.js';
import { $, emptyRow } from './ui.js';

const limits = { preset: '', targets: [] };

function limitsMessage(text, failed) {
  $('limits-result').textContent = text;
  $('limits-result').className = failed ? 'error' : '';
}

function unitOf(target) {
  return unitText(target.kind === 'thermal' ? 'C' : target.unit);
}

function field(name, value, title) {
  const input = document.createElement('input');
  input.className = 'limit-' + name;
  input.inputMode = 'decimal';
  input.size = 7;
  input.value = value;
  input.title = title;
  return input;
}

/** One row per calibrated target of the preset: four fields for a value, a choice for a state. */
function renderLimits(preset) {
  limits.preset = preset ? preset.preset : '';
  limits.targets = preset ? preset.targets : [];
  const body = $('limits-table').tBodies[0];
  const fresh = document.createElement('tbody');
  limits.targets.forEach((target, i) => {
    const tr = fresh.insertRow();
    tr.dataset.index = i;
    tr.insertCell().textContent = target.name || target.kind + ' ' + i;
    const fields = limitFields(target);
    if (statesKind(target.kind)) {
      const cell = tr.insertCell();
      cell.colSpan = 4;
      const select = document.createElement('select');
      select.className = 'limit-state';
      select.add(new Option(t('no limits'), ''));
      for (const [words, code] of stateChoices(target)) select.add(new Option(t('expected {state}', { state: words }), String(code)));
      select.value = fields.state;
      cell.appendChild(select);
    } else {
      tr.insertCell().appendChild(field('low', fields.low, t('normal band: low')));
      tr.insertCell().appendChild(field('high', fields.high, t('normal band: high')));
      tr.insertCell().appendChild(field('alarm-low', fields.alarmLow,
        t('alarm below this (between it and the normal low: warning)')));
      tr.insertCell().appendChild(field('alarm-high', fields.alarmHigh,
        t('alarm above this (between it and the normal high: warning)')));
    }
    tr.insertCell().textContent = unitOf(target);
  });
  if (!limits.targets.length) {
    emptyRow(fresh, 6, t(limits.preset ? 'This preset has no calibrated target yet.' : 'Load a preset to set its limits.'));
  }
  $('limits-save').disabled = !limits.targets.length;
  body.parentNode.replaceChild(fresh, body);
}

/** The preset's targets with the limits typed in; throws naming the target and the field. */
function editedTargets() {
  return limits.targets.map((target, i) => {
    const row = $('limits-table').querySelector('tr[data-index="' + i + '"]');
    const value = (name) => row.querySelector('.limit-' + name).value;
    const fields = statesKind(target.kind) ? { state: value('state') }
      : { low: value('low'), high: value('high'), alarmLow: value('alarm-low'), alarmHigh: value('alarm-high') };
    try {
      return withLimits(target, limitKeys(target, fields));
    } catch (err) {
      throw new Error((target.name || t('target') + ' ' + i) + ': ' + err.message);
    }
  });
}

function saveLimits() {
  let targets;
  try {
    targets = editedTargets();
  } catch (err) {
    limitsMessage(err.message + ' (' + t('nothing saved') + ')', true);
    return;
  }
  const preset = limits.preset;
  limitsMessage(t('saving…'));
  control('calibration_control', 'upload', { preset, targets })
    .then(() => control('calibration_control', 'get', { preset }))
    .then((text) => {
      const answer = JSON.parse(text);
      store.set('preset', { preset: answer.preset, targets: answer.targets });
      limitsMessage(t('limits saved: the next patrol judges its readings by them'));
    })
    .catch((err) => limitsMessage(t('refused') + ': ' + err.message + ' (' + t('nothing saved') + ')', true));
}

export function init() {
  $('limits-save').addEventListener('click', saveLimits);
  store.on('preset', renderLimits);
  renderLimits(null);
}
