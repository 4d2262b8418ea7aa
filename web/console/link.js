/* The link to the robot: one rosbridge websocket (roslib.js, loaded as a classic script before the
   modules: the global ROSLIB), the bridge's challenge authentication, and commands sent as the backend
   ("server") with the names, types and strings of docs/interface.md. Panels register their
   subscriptions here; the link makes them again on every (re)connection, after authenticating. */
import { t } from './i18n.js';
import { authFields } from './auth.js';
import * as store from './state.js';
import { $, log } from './ui.js';

const SENDER = 'server';
const RECONNECT_MS = 2000;
const AUTH_LIFETIME_S = 12 * 3600;  // the auth op's end: an operator's shift
// The acks the Replies panel lists (every command topic's answer).
const ACKS = ['control_ack', 'terrace_ack', 'camera_ack', 'infrared_ack', 'virtual_obstacle_ack', 'voice_ack', 'mode_ack'];

const link = { ros: null, topics: {}, services: {}, transId: 1, authRequired: false, waitingForToken: false,
  session: 0 };
const subscriptions = [];   // [name, type, options, handler] in registration order
const ackHandlers = [];
const closeHandlers = [];

/** Subscribe ``handler`` to a topic on this and every later connection. */
export function subscribe(name, type, options, handler) {
  subscriptions.push([name, type, options, handler]);
}

/** ``handler(ackName, msg)`` for every GeneralAck the page receives (after it is logged). */
export function onAck(handler) {
  ackHandlers.push(handler);
}

/** ``handler()`` when the link drops: held buttons stop acting. */
export function onClose(handler) {
  closeHandlers.push(handler);
}

/** The roslib topic of this connection (one per name and compression). */
export function topic(name, type, options) {
  const key = name + '|' + (options && options.compression || '');
  if (!link.topics[key]) {
    link.topics[key] = new ROSLIB.Topic(Object.assign({ ros: link.ros, name, messageType: type }, options || {}));
  }
  return link.topics[key];
}

/** The spec's header of a command: the backend as sender, trans_id counting up from 1 per page load. */
export function header() {
  return { sender: SENDER, receiver: '', trans_id: link.transId++ };
}

/** This connection's heartbeat session number (docs/interface.md, "Heartbeat and status", Sessions):
    a random non-zero uint32 drawn on every (re)connection, the trans_id of its server_status and of
    its `acquire server`. */
export function session() {
  return link.session;
}

/** The trans_id the next command will carry (to recognise its ack). */
export function nextTransId() {
  return link.transId;
}

/** A GeneralCmd on a *_cmd topic. */
export function command(name, cmd, data) {
  topic(name, 'inspection_robot/GeneralCmd').publish(new ROSLIB.Message(
    Object.assign(header(), { cmd, data: data === undefined ? '' : String(data) })));
}

/** A message of another type on a topic, with the header. */
export function publish(name, type, fields) {
  topic(name, type).publish(new ROSLIB.Message(Object.assign(header(), fields)));
}

/** One ControlService request; resolves with the reply's data on `success`, rejects with the robot's
    own failure text otherwise. ``quiet`` keeps bulky successful replies (file chunks) out of the log. */
export function control(name, cmd, data, quiet) {
  const services = link.services;
  if (!services[name] || services[name].ros !== link.ros) {
    services[name] = new ROSLIB.Service({ ros: link.ros, name, serviceType: 'inspection_robot/ControlService' });
  }
  const request = Object.assign(header(), { cmd,
    data: data === undefined ? '' : typeof data === 'string' ? data : JSON.stringify(data) });
  return new Promise((resolve, reject) => {
    services[name].callService(new ROSLIB.ServiceRequest(request), (reply) => {
      const ok = reply.ack === 'success';
      if (!ok || !quiet) log(name + ' ' + cmd + ' #' + reply.trans_id + ' ' + reply.ack + ': ' + reply.data.slice(0, 300), !ok);
      if (ok) resolve(reply.data); else reject(new Error(reply.data));
    }, (error) => {
      log(name + ' ' + cmd + ': ' + error, true);
      reject(new Error(String(error)));
    });
  });
}

/** A roslib ActionClient of this connection (a new one after a reconnection). */
export function actionClient(previous, serverName, actionName) {
  if (previous && previous.ros === link.ros) return previous;
  return new ROSLIB.ActionClient({ ros: link.ros, serverName, actionName });
}

function setLink(text, up) {
  const element = $('link');
  element.textContent = t(text);
  element.className = 'link ' + (up ? 'up' : 'down');
}

function connect() {
  // the console's own websocket path: the bridge gives it the console's role (docs/interface.md, Backend surface)
  const url = (location.protocol === 'https:' ? 'wss://' : 'ws://') + location.host + '/console/link';
  const token = sessionStorage.getItem('robot-token');
  link.waitingForToken = link.authRequired && !token;
  if (link.waitingForToken) {   // the robot closes a connection that does not authenticate in time
    askToken($('auth-error').textContent);
    return;
  }
  const ros = new ROSLIB.Ros();
  link.ros = ros;
  link.session = 1 + crypto.getRandomValues(new Uint32Array(1))[0] % 0xfffffffe;
  link.topics = {};
  let opened = false;
  ros.on('connection', () => {
    opened = true;
    store.set('connected', true);
    setLink('connected', true);
    log(t('connected to {url}', { url }));
  });
  ros.on('status', (msg) => {
    log('robot: ' + msg.level + ': ' + msg.msg, msg.level === 'error');
    if (/authentication failed|failed authentications/.test(msg.msg)) {
      askToken(t('The robot refused the token ({reason}).', { reason: msg.msg }));
    }
  });
  ros.on('error', () => setLink('link error', false));
  ros.on('close', () => {
    store.set('connected', false);
    closeHandlers.forEach((handler) => handler());
    setLink(opened ? 'disconnected: reconnecting…' : 'no link: retrying…', false);
    if (opened) log(t('link to the robot lost; reconnecting'), true);
    setTimeout(connect, RECONNECT_MS);
  });
  ros.connect(url);
  if (link.authRequired) {
    authenticate(ros, token);
  } else {
    subscribeAll();
  }
}

/* Ask the robot for a nonce, answer with the MAC over it (never the token), then subscribe: the
   robot handles a connection's messages in order, so the subscriptions follow the auth op. */
function authenticate(ros, token) {
  const onChallenge = (event) => {
    if (typeof event.data !== 'string' || event.data.indexOf('"auth_challenge"') < 0) return;
    const challenge = JSON.parse(event.data);
    if (challenge.op !== 'auth_challenge') return;
    ros.socket.removeEventListener('message', onChallenge);
    const f = authFields(token, challenge, 'console', location.host, AUTH_LIFETIME_S);
    ros.authenticate(f.mac, f.client, f.dest, f.rand, f.t, f.level, f.end);
    subscribeAll();
  };
  ros.socket.addEventListener('message', onChallenge);   // roslib.js passes on no op it does not know
  ros.callOnConnection({ op: 'auth_challenge' });
}

function askToken(reason) {
  $('auth-error').textContent = reason;
  sessionStorage.removeItem('robot-token');
  if (!$('auth').open) $('auth').showModal();
}

function onAckMessage(name, msg) {
  log(name + ' #' + msg.trans_id + ' ' + msg.ack + (msg.data ? ': ' + msg.data : ''), msg.ack !== 'success');
  ackHandlers.forEach((handler) => handler(name, msg));
}

function subscribeAll() {
  for (const ack of ACKS) topic(ack, 'inspection_robot/GeneralAck').subscribe((msg) => onAckMessage(ack, msg));
  for (const [name, type, options, handler] of subscriptions) topic(name, type, options).subscribe(handler);
}

/** Ask config.json whether the robot wants a token, then connect (and reconnect whenever the link drops). */
export function start() {
  $('auth-form').addEventListener('submit', () => {
    sessionStorage.setItem('robot-token', $('auth-token').value);
    if (link.waitingForToken) connect();
    else if (link.ros) link.ros.close();   // 'close' reconnects with the token
  });
  fetch('config.json', { cache: 'no-store' })
    .then((response) => response.json())
    .then((config) => { link.authRequired = !!config.auth_required; })
    .catch(() => log('config.json unreadable: assuming no authentication', true))
    .then(connect);
}
