/* Needs review: readings the robot doubts (task_control review_queue) with their annotated picture,
   confirmed or corrected by a named reviewer (task_control review). */
import { t, timeText, unitText } from './i18n.js';
import { displayText, readingText, statusTask } from './decode.js';
import { fetchPicture } from './files.js';
import { control } from './link.js';
import * as store from './state.js';
import { $, coalesced } from './ui.js';

const REVIEW_LIMIT = 20;
const review = { key: null };

function reviewMessage(text, failed) {
  $('review-result').textContent = text;
  $('review-result').className = failed ? 'error' : '';
}

/** Ask for the queue again when the task, its progress or its state changed: a preset recorded may have
    grown it. */
function reviewOnChange(status) {
  const { key } = statusTask(status);
  if (key === review.key) return;
  review.key = key;
  queryReview();
}

const queryReview = coalesced(() => control('task_control', 'review_queue', { limit: REVIEW_LIMIT }, true)
  .then((text) => renderReview(JSON.parse(text)))
  .catch((err) => reviewMessage(t('review queue refused') + ': ' + err.message, true)));

/** One item per reading: its annotated picture, the robot's value and reason, confirm / correct. */
function renderReview(rows) {
  $('review-count').textContent = rows.length ? '(' + rows.length + (rows.length >= REVIEW_LIMIT ? '+' : '') + ')' : '';
  const list = $('review-list');
  const fresh = document.createElement('div');
  fresh.id = 'review-list';
  for (const r of rows) {
    const item = document.createElement('div');
    item.className = 'review-item';
    item.dataset.id = r.id;
    const figure = document.createElement('div');
    if (r.picture) {
      const img = document.createElement('img');
      img.alt = r.picture;
      figure.appendChild(img);
      fetchPicture(r.picture).then((url) => { img.src = url; })
        .catch((err) => { figure.textContent = t('picture') + ': ' + err.message; });
    } else {
      figure.textContent = t('no picture');
    }
    const text = document.createElement('div');
    text.className = 'review-text';
    const what = document.createElement('div');
    what.textContent = (r.target_name || r.kind + ' ' + r.target) + ' · ' + r.task_id + ' '
      + t('stop {i}', { i: r.stop + 1 }) + (r.stop_name ? ' (' + r.stop_name + ')' : '') + ' · ' + timeText(r.time);
    const value = document.createElement('div');
    value.className = r.alarm === 'check' ? 'check' : '';
    value.textContent = t('robot') + ': ' + readingText(r) + ' (' + t('confidence {c}', { c: r.confidence }) + ')'
      + (r.alarm === 'check' ? ' · ' + t('CHECK: outside its band') : '');
    const form = document.createElement('form');
    form.className = 'row';
    const input = document.createElement('input');
    input.type = 'number';
    input.step = 'any';
    input.required = true;
    input.className = 'review-value';
    input.placeholder = t('true value');
    const correct = document.createElement('button');
    correct.type = 'submit';
    correct.className = 'review-correct';
    correct.textContent = t('correct');
    const confirm = document.createElement('button');
    confirm.type = 'button';
    confirm.className = 'review-confirm';
    confirm.textContent = t('confirm {value}', { value: r.display ? displayText(r.display, r)
      : Number(r.value.toPrecision(4)) + (r.unit ? ' ' + unitText(r.unit) : '') });
    confirm.addEventListener('click', () => settle(r, null, item));
    form.addEventListener('submit', (event) => {
      event.preventDefault();
      settle(r, Number(input.value), item);
    });
    form.append(input, correct, confirm);
    text.append(what, value, form);
    item.append(figure, text);
    fresh.appendChild(item);
  }
  if (!rows.length) {
    const empty = document.createElement('p');
    empty.className = 'hint';
    empty.textContent = t('Nothing to review: every doubted reading has been confirmed or corrected.');
    fresh.appendChild(empty);
  }
  list.parentNode.replaceChild(fresh, list);
}

/** review one reading: ``value`` the true value, or null to confirm the robot's. */
function settle(row, value, item) {
  const by = $('review-by').value.trim();
  if (!by) {
    reviewMessage(t('type your name in "reviewer" first'), true);
    $('review-by').focus();
    return;
  }
  if (value !== null && !Number.isFinite(value)) {
    reviewMessage(t('the true value must be a number'), true);
    return;
  }
  item.querySelectorAll('button, input').forEach((e) => { e.disabled = true; });
  control('task_control', 'review', { id: row.id, value, by })
    .then((text) => {
      const done = JSON.parse(text);
      reviewMessage(t('reading {id} ({target})', { id: done.id, target: done.target_name }) + ': '
        + (value === null ? t('confirmed') : t('corrected to {value}', { value: done.review_value })) + ' '
        + t('by {name}', { name: done.review_by }));
      queryReview();
      store.emit('readings-changed', row.task_id);
    })
    .catch((err) => {
      reviewMessage(t('review refused') + ': ' + err.message, true);
      item.querySelectorAll('button, input').forEach((e) => { e.disabled = false; });
    });
}

export function init() {
  window.consoleReview = { ids: () => Array.from(document.querySelectorAll('.review-item'), (e) => Number(e.dataset.id)) };
  $('review-refresh').addEventListener('click', queryReview);
  store.on('task', reviewOnChange);
}
