/* The operator console's entry point (index.html loads it as a module, no build step): each panel wires
   its part of the page and registers its subscriptions, then the link connects. One module per panel:
   status, drive (heartbeat, e-stop, teleop), head, images, map (goals, obstacles), planner (patrol
   planner; its arithmetic in planning.js), schedules (routines, schedules), calibration (presets), limits
   (a preset's bands; their checks in bands.js), patrol, results (readings), trends (the chart;
   its data in trend_data.js), review, alarms (open
   alarms, acknowledge, the header's banner); link (roslib, auth, commands) and decoding (decode.js,
   auth.js) apart; shared helpers in ui.js; words in the operator's language through i18n.js. Panels never call each other: what more than one reads, and
   the news they give each other, go through the store (state.js). */
import * as alarms from './alarms.js';
import * as calibration from './calibration.js';
import * as drive from './drive.js';
import * as head from './head.js';
import * as images from './images.js';
import * as limits from './limits.js';
import { start } from './link.js';
import * as map from './map.js';
import * as patrol from './patrol.js';
import * as planner from './planner.js';
import * as results from './results.js';
import * as review from './review.js';
import * as schedules from './schedules.js';
import * as status from './status.js';
import * as trends from './trends.js';
import { LANGUAGES, rememberLanguage, startLanguage, t, translatePage, useLanguage } from './i18n.js';
import { $ } from './ui.js';

/** The page in its language (the operator's choice in this browser, else the site's: config.json), then
    the panels, then the link. A language switch reloads the page: every panel writes its text anew. */
function begin(config, catalogue) {
  const chosen = useLanguage(startLanguage(config.language), catalogue);
  translatePage(document.body);
  document.title = t(document.title);
  const select = $('language');
  for (const [code, words] of Object.entries(LANGUAGES)) select.add(new Option(words, code));
  select.value = chosen;
  select.addEventListener('change', () => {
    rememberLanguage(select.value);
    location.reload();
  });
  for (const panel of [status, drive, head, images, map, planner, schedules, calibration, limits, patrol, results,
    trends, review, alarms]) {
    panel.init();
  }
  start();
}

const json = (path) => fetch(path, { cache: 'no-cache' }).then((r) => (r.ok ? r.json() : {})).catch(() => ({}));
Promise.all([json('config.json'), json('strings.json')]).then(([config, catalogue]) => begin(config, catalogue));
