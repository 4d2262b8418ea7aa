/* The operator's language: every word of the page from one catalogue (strings.json, shared with the
   patrol report: src/inspection_robot/i18n.py). The English text is the key (gettext style):
   ``t('stop {i} of {n}', {i, n})`` gives the zh-CN text with the values put in, English as written. The
   site's language (config.json, the site file's ``language``) is the default; the operator's choice
   in the page is kept in this browser (localStorage). Static text of index.html is translated by
   walking its text nodes and title/placeholder attributes; the robot's own reasons stay as the robot
   wrote them (they are the interface's words, in English). Dates and times use the language's locale
   and the 24-hour clock. */

export const LANGUAGES = { 'zh-CN': '中文', en: 'English' };
export const DEFAULT_LANGUAGE = 'zh-CN';
const STORAGE_KEY = 'inspection_robot.language';
const lang = { current: 'en', strings: {}, original: new WeakMap() };

/** Put ``params`` into ``text`` at its {name} places (a missing one stays as written). */
export function fill(text, params) {
  return params ? text.replace(/\{(\w+)\}/g, (all, name) => (name in params ? String(params[name]) : all)) : text;
}

/** ``text`` (the English original) in the current language, with ``params`` filled in. */
export function t(text, params) {
  const translated = lang.current === 'en' ? text : lang.strings[text];
  return fill(translated === undefined ? text : translated, params);
}

/** Use ``catalogue`` ({language: {english: text}}, strings.json) for ``language``; unknown: English. */
export function useLanguage(language, catalogue) {
  lang.current = language in LANGUAGES ? language : 'en';
  lang.strings = (catalogue && catalogue[lang.current]) || {};
  return lang.current;
}

export function language() {
  return lang.current;
}

/** A time (unix s) in the current language's locale, 24-hour clock. */
export function timeText(unixSeconds) {
  return new Date(unixSeconds * 1000).toLocaleString(lang.current, { hour12: false });
}

/** A unit for people: degrees Celsius as °C (the interface writes ``C``). */
export function unitText(unit) {
  return unit === 'C' ? '°C' : unit || '';
}

/** The language to start with: the operator's last choice in this browser, else the site's. */
export function startLanguage(siteLanguage) {
  let chosen = null;
  try {
    chosen = window.localStorage.getItem(STORAGE_KEY);
  } catch (err) {
    chosen = null;   // storage off: the site's language every time
  }
  return chosen in LANGUAGES ? chosen : siteLanguage in LANGUAGES ? siteLanguage : DEFAULT_LANGUAGE;
}

export function rememberLanguage(language) {
  try {
    window.localStorage.setItem(STORAGE_KEY, language);
  } catch (err) {
    // storage off: the choice lasts this page load
  }
}

/** HTML text as the catalogue keys it: runs of white space (line breaks of the source) as one space. */
const words = (text) => text.replace(/\s+/g, ' ').trim();

/** Translate the static text of ``root`` (text nodes, title and placeholder), from the English originals
    (kept, so switching back and forth never translates a translation). */
export function translatePage(root) {
  const walker = document.createTreeWalker(root, NodeFilter.SHOW_TEXT);
  const nodes = [];
  while (walker.nextNode()) nodes.push(walker.currentNode);
  for (const node of nodes) {
    if (node.parentNode && /^(SCRIPT|STYLE|TEXTAREA|OPTION)$/.test(node.parentNode.tagName)) continue;
    if (node.parentNode && node.parentNode.closest('[data-dynamic]')) continue;   // panels write these
    if (!lang.original.has(node)) lang.original.set(node, node.nodeValue);
    const original = lang.original.get(node);
    const text = original.trim();
    if (!text) continue;
    node.nodeValue = original.replace(text, t(words(text)));
  }
  for (const el of root.querySelectorAll('[title], [placeholder], option')) {
    for (const attribute of ['title', 'placeholder']) {
      if (!el.hasAttribute(attribute)) continue;
      const key = 'i18n' + attribute;
      if (!(key in el.dataset)) el.dataset[key] = el.getAttribute(attribute);
      el.setAttribute(attribute, t(words(el.dataset[key])));
    }
    if (el.tagName === 'OPTION' && !el.closest('[data-dynamic]')) {
      if (!('i18ntext' in el.dataset)) el.dataset.i18ntext = el.textContent;
      if (!el.hasAttribute('value')) el.setAttribute('value', el.dataset.i18ntext);   // the value stays English
      el.textContent = t(words(el.dataset.i18ntext));
    }
  }
  document.documentElement.lang = lang.current;
}
