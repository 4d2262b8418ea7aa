/* Trends: several meters on one chart (uPlot, vendored from the npm registry by scripts/setup and loaded
   on first use), time on the x axis, one y axis per unit, each reading coloured by its own state, the
   normal and alarm bands each reading was judged by (so a band drawn is the band of its time), values
   under the cursor in the legend, drag to zoom (double click: all), a time range, and CSV export. A click
   on a meter in the readings table adds it (news 'trend-meter' from results.js). */
import { t, timeText, unitText } from './i18n.js';
import { control } from './link.js';
import * as store from './state.js';
import { MAX_TREND_METERS, POINT_COLOURS, TREND_RANGES, trendCsv, trendTable } from './trend_data.js';
import { $ } from './ui.js';

const LINE_COLOURS = ['#455a64', '#6d4c41', '#00695c', '#283593', '#ad1457', '#558b2f'];
const trends = { meters: [], days: 90, chart: null, uPlot: null };

function trendMessage(text, failed) {
  $('trend-meter').textContent = text;
  $('trend-meter').className = failed ? 'error' : '';
}

/** uPlot, imported once when the first chart is drawn (node imports this module without it). */
function library() {
  if (!trends.uPlot) trends.uPlot = import('./vendor/uPlot.esm.js').then((m) => m.default);
  return trends.uPlot;
}

function query(meter) {
  const since = Date.now() / 1000 - trends.days * 86400;
  return control('task_control', 'query_results', { target: meter.target, from: since, limit: 5000 }, true)
    .then((text) => { meter.rows = JSON.parse(text); });
}

/** Add ``meter`` {target, unit} (or ask again for it), dropping the oldest beyond MAX_TREND_METERS. */
function addMeter(meter) {
  const known = trends.meters.find((m) => m.target === meter.target);
  const entry = known || { target: meter.target, unit: meter.unit || '', rows: [] };
  if (!known) trends.meters = trends.meters.concat([entry]).slice(-MAX_TREND_METERS);
  trendMessage(entry.target + ' (' + t('loading…') + ')');
  query(entry).then(draw).catch((err) => trendMessage(entry.target + ': ' + t('query refused') + ': ' + err.message, true));
}

function reloadAll() {
  Promise.all(trends.meters.map(query)).then(draw)
    .catch((err) => trendMessage(t('query refused') + ': ' + err.message, true));
}

/** Coloured dots per reading, by the reading's state (uPlot's draw hook). */
function dotsHook(table, valueIndex) {
  return (u) => {
    const ctx = u.ctx;
    table.series.forEach((s, m) => {
      if (!u.series[valueIndex[m]].show) return;
      const scale = u.series[valueIndex[m]].scale;
      s.values.forEach((v, i) => {
        if (v === null) return;
        ctx.fillStyle = POINT_COLOURS[s.states[i]] || '#333';
        ctx.beginPath();
        ctx.arc(u.valToPos(table.x[i], 'x', true), u.valToPos(v, scale, true), 4 * devicePixelRatio, 0, 2 * Math.PI);
        ctx.fill();
      });
    });
  };
}

function draw() {
  return library().then((uPlot) => {
    const table = trendTable(trends.meters);
    const units = Array.from(new Set(table.series.map((s) => s.unit || '(no unit)')));
    const data = [table.x];
    const series = [{ label: t('time'), value: (u, x) => (x === null ? '' : timeText(x)) }];
    const bands = [];
    const valueIndex = [];
    table.series.forEach((s, m) => {
      const scale = s.unit || '(no unit)';
      const colour = LINE_COLOURS[m % LINE_COLOURS.length];
      const unit = s.unit ? ' ' + unitText(s.unit) : '';
      const fmt = (u, v) => (v === null || v === undefined ? '–' : Number(v.toPrecision(6)) + unit);
      valueIndex.push(data.length);
      data.push(s.values);
      series.push({ label: s.target, scale, stroke: colour, width: 1.5, spanGaps: true, points: { show: false },
        value: fmt });
      const limit = (label, values, dash) => {
        data.push(values);
        series.push({ label: s.target + ' ' + t(label), scale, stroke: colour, width: 1, dash, spanGaps: false,
          points: { show: false }, value: fmt });
        return data.length - 1;
      };
      const high = limit('normal high', s.high, [6, 4]);
      const low = limit('normal low', s.low, [6, 4]);
      bands.push({ series: [high, low], fill: 'rgba(46, 125, 50, 0.10)' });
      limit('alarm above', s.alarmHigh, [2, 3]);
      limit('alarm below', s.alarmLow, [2, 3]);
    });
    const axes = [{}].concat(units.map((unit, i) => ({ scale: unit, side: i % 2 ? 1 : 3,
      label: unit === '(no unit)' ? t(unit) : unitText(unit), grid: { show: i === 0 }, size: 60 })));
    const scales = { x: { time: true } };
    units.forEach((unit) => { scales[unit] = { auto: true }; });
    const width = Math.max(320, $('trend').clientWidth || 640);
    const options = { width, height: 260, series, bands, axes, scales, cursor: { drag: { x: true, y: false } },
      hooks: { draw: [dotsHook(table, valueIndex)] }, legend: { live: true } };
    if (trends.chart) trends.chart.destroy();
    $('trend').textContent = '';
    trends.chart = table.x.length ? new uPlot(options, data, $('trend')) : null;
    const points = table.series.reduce((n, s) => n + s.points, 0);
    $('trend').dataset.points = String(points);
    $('trend').dataset.meters = trends.meters.map((m) => m.target).join(',');
    trendMessage(trends.meters.length ? trends.meters.map((m) => m.target).join(', ') + ': '
      + t('{n} reading(s) in {days} days', { n: points, days: trends.days }) : t('(click a target above)'));
  }).catch((err) => trendMessage(t('trend not drawn') + ': ' + err.message, true));
}

function exportCsv() {
  if (!trends.meters.length) {
    trendMessage(t('add a meter first (click a target above)'), true);
    return;
  }
  const url = URL.createObjectURL(new Blob([trendCsv(trends.meters)], { type: 'text/csv' }));
  const a = document.createElement('a');
  a.href = url;
  a.download = 'trend_' + trends.meters.map((m) => m.target.replace(/[^A-Za-z0-9_-]+/g, '_')).join('+') + '.csv';
  document.body.appendChild(a);
  a.click();
  a.remove();
  setTimeout(() => URL.revokeObjectURL(url), 1000);
}

export function init() {
  window.consoleTrends = { meters: () => trends.meters.map((m) => m.target), csv: () => trendCsv(trends.meters) };
  const range = $('trend-range');
  for (const [words, days] of Object.entries(TREND_RANGES)) range.add(new Option(t(words), String(days)));
  range.value = String(trends.days);
  range.addEventListener('change', () => {
    trends.days = Number(range.value);
    reloadAll();
  });
  $('trend-clear').addEventListener('click', () => {
    trends.meters = [];
    draw();
  });
  $('trend-csv').addEventListener('click', exportCsv);
  store.on('trend-meter', addMeter);
}
