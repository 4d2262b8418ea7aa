/* The operator console: everything goes through the robot's rosbridge websocket (roslib.js), with
   the names, types and strings of docs/interface.md. Commands are sent as the backend ("server"). */
(function () {
  'use strict';

  const SENDER = 'server';
  const DRIVE_PERIOD_MS = 100;        // move_cmd repeat while a drive key is held (robot cmd_timeout 0.5 s)
  const HEARTBEAT_PERIOD_MS = 1000;   // server_status while the page acts as the backend
  const RECONNECT_MS = 2000;
  const YAW_RATE = 0.5;               // rad/s when turning
  const AUTH_LIFETIME_S = 12 * 3600;  // the auth op's end: an operator's shift

  const $ = (id) => document.getElementById(id);
  const state = { ros: null, topics: {}, transId: 1, status: null, authRequired: false, connected: false,
    waitingForToken: false };

  // ------------------------------------------------------------------ log of the robot's replies
  function log(text, failed) {
    const item = document.createElement('li');
    item.textContent = new Date().toLocaleTimeString() + '  ' + text;
    if (failed) item.className = 'failed';
    const list = $('log');
    list.insertBefore(item, list.firstChild);
    while (list.children.length > 200) list.removeChild(list.lastChild);
  }

  // ------------------------------------------------------------------ connection
  function topic(name, type, options) {
    const key = name + '|' + (options && options.compression || '');
    if (!state.topics[key]) {
      state.topics[key] = new ROSLIB.Topic(Object.assign({ ros: state.ros, name, messageType: type }, options || {}));
    }
    return state.topics[key];
  }

  function header() {
    return { sender: SENDER, receiver: '', trans_id: state.transId++ };
  }

  function command(name, cmd, data) {
    topic(name, 'inspection_robot/GeneralCmd').publish(new ROSLIB.Message(
      Object.assign(header(), { cmd, data: data === undefined ? '' : String(data) })));
  }

  function setLink(text, up) {
    const link = $('link');
    link.textContent = text;
    link.className = 'link ' + (up ? 'up' : 'down');
  }

  function connect() {
    const url = (location.protocol === 'https:' ? 'wss://' : 'ws://') + location.host + '/';
    const token = sessionStorage.getItem('robot-token');
    state.waitingForToken = state.authRequired && !token;
    if (state.waitingForToken) {   // the robot closes a connection that does not authenticate in time
      askToken($('auth-error').textContent);
      return;
    }
    const ros = new ROSLIB.Ros();
    state.ros = ros;
    state.topics = {};
    let opened = false;
    ros.on('connection', () => {
      opened = true;
      state.connected = true;
      setLink('connected', true);
      log('connected to ' + url);
    });
    ros.on('status', (msg) => {
      log('robot: ' + msg.level + ': ' + msg.msg, msg.level === 'error');
      if (/authentication failed|failed authentications/.test(msg.msg)) {
        askToken('The robot refused the token (' + msg.msg + ').');
      }
    });
    ros.on('error', () => setLink('link error', false));
    ros.on('close', () => {
      state.connected = false;
      stopDriving();
      stopHead();
      setLink(opened ? 'disconnected: reconnecting…' : 'no link: retrying…', false);
      if (opened) log('link to the robot lost; reconnecting', true);
      setTimeout(connect, RECONNECT_MS);
    });
    ros.connect(url);
    if (state.authRequired) {
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
      const f = RobotAuth.authFields(token, challenge, 'console', location.host, AUTH_LIFETIME_S);
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

  $('auth-form').addEventListener('submit', () => {
    sessionStorage.setItem('robot-token', $('auth-token').value);
    if (state.waitingForToken) connect();
    else if (state.ros) state.ros.close();   // 'close' reconnects with the token
  });

  // ------------------------------------------------------------------ subscriptions
  function subscribeAll() {
    topic('robot_status', 'inspection_robot/RobotStatus', { throttle_rate: 0, queue_length: 1 }).subscribe(onStatus);
    for (const ack of ['control_ack', 'terrace_ack', 'camera_ack', 'infrared_ack', 'virtual_obstacle_ack',
      'voice_ack', 'mode_ack']) {
      topic(ack, 'inspection_robot/GeneralAck').subscribe((msg) => onAck(ack, msg));
    }
    topic('preset_scale_ack', 'inspection_robot/PresetScaleAck').subscribe(onPresetAck);
    topic('terrace_state', 'sensor_msgs/JointState', { throttle_rate: 200, queue_length: 1 }).subscribe(onHead);
    topic('camera/image_raw', 'sensor_msgs/Image', { compression: 'cbor', queue_length: 1 })
      .subscribe((msg) => drawImage($('picture'), msg));
    topic('thermal/image_raw', 'sensor_msgs/Image', { compression: 'cbor', queue_length: 1 })
      .subscribe((msg) => drawImage($('thermal'), msg, state.hottest));
    topic('thermal/hottest', 'inspection_robot/GeneralTopic', { queue_length: 1 }).subscribe(onHottest);
    topic('map', 'nav_msgs/OccupancyGrid', { compression: 'cbor', queue_length: 1 }).subscribe(onMap);
    topic('plan', 'nav_msgs/Path', { queue_length: 1 }).subscribe(onPlan);
    // move_base republishes the virtual layer on every change (whoever made it): then ask for the list.
    topic('virtual_obstacle_map', 'nav_msgs/OccupancyGrid', { compression: 'cbor', queue_length: 1 })
      .subscribe(queryObstacles);
    topic('task_status', 'inspection_robot/GeneralTopic', { queue_length: 1 }).subscribe(onTaskStatus);
  }

  // ------------------------------------------------------------------ status
  const statusRows = {};
  window.consoleStats = { status: 0 };   // statuses rendered, for the benchmark
  let statusFrame = 0;
  function onStatus(msg) {
    state.status = msg;
    if (!statusFrame) statusFrame = requestAnimationFrame(renderStatus);
  }

  /** At most once per animation frame, whatever the rate: the newest status only. */
  function renderStatus() {
    statusFrame = 0;
    const msg = state.status;
    window.consoleStats.status += 1;
    const decoded = RobotDecode.decodeStatus(msg);
    $('mode').textContent = 'mode: ' + RobotDecode.MODES[msg.mode];
    const alarms = $('alarms');
    alarms.textContent = decoded.alarms.length ? decoded.alarms.join(' · ') : 'no alarm';
    alarms.className = 'alarms' + (decoded.alarms.length ? ' active' : '');
    // One table row per (name, index) kept across updates: a 10 Hz refresh must not grow the DOM.
    const body = $('status').tBodies[0];
    const seen = {};
    decoded.rows.forEach((row) => {
      const key = row.name + '#' + (seen[row.name] = (seen[row.name] || 0) + 1);
      let tr = statusRows[key];
      if (!tr) {
        tr = statusRows[key] = body.insertRow();
        tr.insertCell().textContent = row.name;
        tr.insertCell();
      }
      tr.cells[1].textContent = row.text;
      tr.className = row.alarm ? 'alarm' : '';
      tr.hidden = false;
    });
    Object.keys(statusRows).forEach((key) => {
      const [name, n] = key.split('#');
      if (Number(n) > (seen[name] || 0)) statusRows[key].hidden = true;
    });
    drawMap();
  }

  function onAck(name, msg) {
    log(name + ' #' + msg.trans_id + ' ' + msg.ack + (msg.data ? ': ' + msg.data : ''), msg.ack !== 'success');
    if (name === 'virtual_obstacle_ack' && state.obstacleQueries.delete(msg.trans_id) && msg.ack === 'success') {
      try {
        state.obstacles = JSON.parse(msg.data);
      } catch (err) {
        log('virtual obstacle list unreadable: ' + err, true);
      }
      drawMap();
    }
  }

  // ------------------------------------------------------------------ heartbeat and e-stop
  function heartbeat() {
    if (state.connected && $('heartbeat').checked) {
      topic('server_status', 'inspection_robot/GeneralTopic').publish(
        new ROSLIB.Message(Object.assign(header(), { data: 'console' })));
    }
  }
  setInterval(heartbeat, HEARTBEAT_PERIOD_MS);
  $('heartbeat').addEventListener('change', heartbeat);

  $('estop').addEventListener('click', () => {
    stopDriving();
    command('control_cmd', 'enable_stop');
  });
  $('estop-release').addEventListener('click', () => command('control_cmd', 'disable_stop'));

  // ------------------------------------------------------------------ teleop
  $('acquire').addEventListener('click', () => {
    // robot_control refuses `acquire server` while the backend is offline: heartbeat first, then ask.
    $('heartbeat').checked = true;
    heartbeat();
    const started = Date.now();
    const tryAcquire = () => {
      if ((!state.status || state.status.offline_warn) && Date.now() - started < 10000) {
        setTimeout(tryAcquire, 200);
        return;
      }
      command('mode_cmd', 'acquire', 'server');
      setTimeout(() => {
        if (!state.status || state.status.mode !== 1) log('acquire: control not granted yet (mode '
          + (state.status ? RobotDecode.MODES[state.status.mode] : '?') + ')', true);
      }, 1500);
    };
    tryAcquire();
  });
  $('release').addEventListener('click', () => {
    stopDriving();
    command('mode_cmd', 'release', 'server');
  });
  $('speed').addEventListener('input', () => { $('speed-out').textContent = $('speed').value; });

  const held = new Set();
  let driveTimer = null;
  let wheelControl = 0;

  function driveCommand() {
    const speed = Number($('speed').value);
    let vx = 0;
    let yaw = 0;
    if (held.has('forward')) vx += speed;
    if (held.has('backward')) vx -= speed;
    if (held.has('left')) yaw += YAW_RATE;
    if (held.has('right')) yaw -= YAW_RATE;
    // Turning alone spins in place (steer mode); with a forward/backward key it steers while driving.
    wheelControl = vx === 0 && yaw !== 0 ? 1 : 0;
    return { vx, yaw };
  }

  function publishMove(vx, yaw) {
    topic('move_cmd', 'inspection_robot/MoveCmd').publish(new ROSLIB.Message(Object.assign(header(), {
      velocity_x: Math.round(vx * 1000), velocity_yaw: Math.round(yaw * 1000), wheel_control: wheelControl })));
  }

  function sendDrive() {
    const { vx, yaw } = driveCommand();
    publishMove(vx, yaw);
  }

  function startDriving(direction) {
    if (direction === 'stop') {
      stopDriving();
      return;
    }
    held.add(direction);
    markHeld();
    sendDrive();
    if (!driveTimer) driveTimer = setInterval(sendDrive, DRIVE_PERIOD_MS);
  }

  function releaseDriving(direction) {
    if (!held.delete(direction)) return;
    markHeld();
    if (held.size) {
      sendDrive();
    } else {
      stopDriving();
    }
  }

  /** One explicit zero move_cmd, then silence (the robot's watchdog covers a lost stop). */
  function stopDriving() {
    const wasDriving = driveTimer !== null || held.size > 0;
    held.clear();
    markHeld();
    if (driveTimer) clearInterval(driveTimer);
    driveTimer = null;
    if (wasDriving && state.connected) publishMove(0, 0);
  }

  function markHeld() {
    document.querySelectorAll('[data-drive]').forEach((b) => b.classList.toggle('held', held.has(b.dataset.drive)));
  }

  const KEYS = { ArrowUp: 'forward', KeyW: 'forward', ArrowDown: 'backward', KeyS: 'backward', ArrowLeft: 'left',
    KeyA: 'left', ArrowRight: 'right', KeyD: 'right', Space: 'stop' };
  function typing(event) {
    return /^(INPUT|TEXTAREA|SELECT)$/.test(event.target.tagName) && event.target.type !== 'range';
  }
  window.addEventListener('keydown', (event) => {
    const direction = KEYS[event.code];
    if (!direction || typing(event)) return;
    event.preventDefault();
    if (!event.repeat) startDriving(direction);
  });
  window.addEventListener('keyup', (event) => {
    const direction = KEYS[event.code];
    if (direction && !typing(event)) releaseDriving(direction);
  });
  // Losing focus loses the key-up: stop rather than drive on.
  window.addEventListener('blur', stopDriving);
  document.addEventListener('visibilitychange', () => { if (document.hidden) stopDriving(); });

  function holdButton(button, press, release) {
    button.addEventListener('pointerdown', (event) => {
      button.setPointerCapture(event.pointerId);
      press();
    });
    for (const type of ['pointerup', 'pointercancel', 'lostpointercapture']) button.addEventListener(type, release);
  }
  document.querySelectorAll('[data-drive]').forEach((b) => {
    holdButton(b, () => startDriving(b.dataset.drive), () => releaseDriving(b.dataset.drive));
  });

  // ------------------------------------------------------------------ head and camera
  let headMoving = false;
  let lensMoving = false;
  function stopHead() {
    if (headMoving && state.connected) command('terrace_cmd', 'terrace_stop');
    if (lensMoving && state.connected) command('camera_cmd', 'camera_stop');
    headMoving = lensMoving = false;
  }
  document.querySelectorAll('[data-head]').forEach((b) => {
    const cmd = b.dataset.head;
    if (cmd === 'terrace_stop') {
      b.addEventListener('click', () => { headMoving = true; stopHead(); });
      return;
    }
    holdButton(b, () => { headMoving = true; command('terrace_cmd', cmd, 'mid_speed'); }, stopHead);
  });
  document.querySelectorAll('[data-lens]').forEach((b) => {
    holdButton(b, () => { lensMoving = true; command('camera_cmd', b.dataset.lens, '0'); }, stopHead);
  });
  document.querySelectorAll('[data-aux]').forEach((b) => {
    b.addEventListener('click', () => command('terrace_cmd', b.dataset.aux));
  });
  $('angle-form').addEventListener('submit', (event) => {
    event.preventDefault();
    const centi = (input) => Math.round(Number(input.value) * 100);
    command('terrace_cmd', 'set_angle', centi($('pan')) + ',' + centi($('tilt')));
  });

  function onHead(msg) {
    const deg = (rad) => (rad * 180 / Math.PI).toFixed(2);
    $('head-angle').textContent = 'now pan ' + deg(msg.position[0]) + '°, tilt ' + deg(msg.position[1]) + '°';
  }

  function bytesOf(data) {
    if (data instanceof Uint8Array) return data;
    if (typeof data === 'string') {   // JSON encoding: base64
      const text = atob(data);
      const out = new Uint8Array(text.length);
      for (let i = 0; i < text.length; i++) out[i] = text.charCodeAt(i);
      return out;
    }
    return Uint8Array.from(data);
  }

  /** A bgr8/rgb8/mono8 sensor_msgs/Image onto a canvas (resized to the picture). */
  function drawImage(canvas, msg, marker) {
    const src = bytesOf(msg.data);
    const ctx = canvas.getContext('2d');
    if (canvas.width !== msg.width || canvas.height !== msg.height) {
      canvas.width = msg.width;
      canvas.height = msg.height;
    }
    const image = ctx.createImageData(msg.width, msg.height);
    const out = image.data;
    const channels = msg.encoding === 'mono8' ? 1 : 3;
    const bgr = msg.encoding === 'bgr8';
    for (let y = 0; y < msg.height; y++) {
      let s = y * msg.step;
      let d = y * msg.width * 4;
      for (let x = 0; x < msg.width; x++, s += channels, d += 4) {
        if (channels === 1) {
          out[d] = out[d + 1] = out[d + 2] = src[s];
        } else {
          out[d] = src[bgr ? s + 2 : s];
          out[d + 1] = src[s + 1];
          out[d + 2] = src[bgr ? s : s + 2];
        }
        out[d + 3] = 255;
      }
    }
    ctx.putImageData(image, 0, 0);
    window.consoleFrames[canvas.id] += 1;
    if (marker) {
      ctx.strokeStyle = '#00e5ff';
      ctx.lineWidth = 2;
      ctx.beginPath();
      ctx.arc(marker.x, marker.y, 8, 0, 2 * Math.PI);
      ctx.moveTo(marker.x - 14, marker.y);
      ctx.lineTo(marker.x + 14, marker.y);
      ctx.moveTo(marker.x, marker.y - 14);
      ctx.lineTo(marker.x, marker.y + 14);
      ctx.stroke();
    }
  }

  function onHottest(msg) {
    try {
      state.hottest = JSON.parse(msg.data);
      $('thermal-caption').textContent = 'thermal: hottest ' + state.hottest.temperature.toFixed(1) + ' °C at ('
        + state.hottest.x + ', ' + state.hottest.y + ')';
    } catch (err) {
      log('thermal/hottest unreadable: ' + err, true);
    }
  }

  $('picture').addEventListener('click', (event) => {
    const canvas = $('picture');
    const rect = canvas.getBoundingClientRect();
    const x = (event.clientX - rect.left) * canvas.width / rect.width;
    const y = (event.clientY - rect.top) * canvas.height / rect.height;
    topic('preset_rotate', 'inspection_robot/PresetRotate').publish(new ROSLIB.Message(Object.assign(header(), {
      width: canvas.width, height: canvas.height,
      delta_x: Math.round(x - canvas.width / 2), delta_y: Math.round(canvas.height / 2 - y) })));
  });

  // ------------------------------------------------------------------ map, goals, virtual obstacles
  const view = { scale: 0, ox: 0, oy: 0 };   // screen = (world - origin) * scale, y up
  let mapImage = null;
  let mapInfo = null;
  let tool = null;
  let draft = [];
  let selected = null;
  let dragging = null;
  let panning = null;
  let goal = null;
  state.obstacles = [];
  state.obstacleQueries = new Set();   // trans_ids of the page's own pending `query` commands

  // For the browser tests: the map transform, and how many live pictures were drawn.
  window.consoleMap = { toScreen: (p) => toScreen(p), ready: () => mapInfo !== null,
    obstacleCount: () => state.obstacles.length };
  window.consoleFrames = { picture: 0, thermal: 0 };

  function onMap(msg) {
    const info = msg.info;
    const cells = msg.data;
    const image = new ImageData(info.width, info.height);
    for (let row = 0; row < info.height; row++) {
      const flipped = (info.height - 1 - row) * info.width;   // row 0 of the grid is the bottom of the map
      for (let col = 0; col < info.width; col++) {
        const v = cells[row * info.width + col];
        const grey = v < 0 ? 160 : 255 - Math.round(v * 2.55);
        const d = (flipped + col) * 4;
        image.data[d] = image.data[d + 1] = image.data[d + 2] = grey;
        image.data[d + 3] = 255;
      }
    }
    mapImage = document.createElement('canvas');
    mapImage.width = info.width;
    mapImage.height = info.height;
    mapImage.getContext('2d').putImageData(image, 0, 0);
    mapInfo = info;
    fitMap();
    drawMap();
  }

  function onPlan(msg) {
    state.plan = msg.poses.map((p) => [p.pose.position.x, p.pose.position.y]);
    drawMap();
  }

  function fitMap() {
    const canvas = $('map');
    const w = mapInfo.width * mapInfo.resolution;
    const h = mapInfo.height * mapInfo.resolution;
    view.scale = Math.min(canvas.width / w, canvas.height / h);
    view.ox = mapInfo.origin.position.x;
    view.oy = mapInfo.origin.position.y + canvas.height / view.scale;
  }

  const toScreen = ([x, y]) => [(x - view.ox) * view.scale, (view.oy - y) * view.scale];
  const toWorld = (sx, sy) => [sx / view.scale + view.ox, view.oy - sy / view.scale];

  function polyline(ctx, points, closed) {
    ctx.beginPath();
    points.forEach((p, i) => {
      const [sx, sy] = toScreen(p);
      if (i) ctx.lineTo(sx, sy); else ctx.moveTo(sx, sy);
    });
    if (closed) ctx.closePath();
  }

  let mapFrame = 0;
  function drawMap() {
    if (!mapFrame) mapFrame = requestAnimationFrame(renderMap);
  }

  function renderMap() {
    mapFrame = 0;
    const canvas = $('map');
    const ctx = canvas.getContext('2d');
    ctx.setTransform(1, 0, 0, 1, 0, 0);
    ctx.fillStyle = '#9e9e9e';
    ctx.fillRect(0, 0, canvas.width, canvas.height);
    if (!mapInfo) return;
    const [mx, my] = toScreen([mapInfo.origin.position.x, mapInfo.origin.position.y]);
    const mw = mapInfo.width * mapInfo.resolution * view.scale;
    const mh = mapInfo.height * mapInfo.resolution * view.scale;
    ctx.imageSmoothingEnabled = false;
    ctx.drawImage(mapImage, mx, my - mh, mw, mh);
    for (const obstacle of state.obstacles) {
      const points = selected && selected.id === obstacle.id ? selected.points : obstacle.points;
      ctx.strokeStyle = selected && selected.id === obstacle.id ? '#ff6d00' : '#d50000';
      ctx.lineWidth = 3;
      polyline(ctx, points, obstacle.closed);
      ctx.stroke();
      if (selected && selected.id === obstacle.id) {
        ctx.fillStyle = '#ff6d00';
        for (const p of points) {
          const [sx, sy] = toScreen(p);
          ctx.fillRect(sx - 4, sy - 4, 8, 8);
        }
      }
    }
    if (draft.length) {
      ctx.strokeStyle = '#d50000';
      ctx.setLineDash([6, 4]);
      polyline(ctx, draft, draft.length > 2);
      ctx.stroke();
      ctx.setLineDash([]);
    }
    if (state.plan && state.plan.length) {
      ctx.strokeStyle = '#1565c0';
      ctx.lineWidth = 2;
      polyline(ctx, state.plan, false);
      ctx.stroke();
    }
    if (goal) {
      const [gx, gy] = toScreen(goal);
      ctx.strokeStyle = '#2e7d32';
      ctx.beginPath();
      ctx.arc(gx, gy, 7, 0, 2 * Math.PI);
      ctx.stroke();
    }
    const s = state.status;
    if (s && s.position && s.position.length >= 2) {
      const [rx, ry] = toScreen(s.position);
      ctx.save();
      ctx.translate(rx, ry);
      ctx.rotate(-s.orientation);
      ctx.fillStyle = '#ffab00';
      ctx.strokeStyle = '#000';
      ctx.lineWidth = 1;
      ctx.beginPath();
      ctx.moveTo(12, 0);
      ctx.lineTo(-8, 7);
      ctx.lineTo(-8, -7);
      ctx.closePath();
      ctx.fill();
      ctx.stroke();
      ctx.restore();
    }
  }

  function setTool(name) {
    tool = tool === name ? null : name;
    draft = [];
    if (tool !== 'edit') selected = null;
    document.querySelectorAll('.tool').forEach((b) => b.classList.toggle('active', b.id === 'tool-' + tool));
    updateObstacleButtons();
    drawMap();
  }
  $('tool-goal').addEventListener('click', () => setTool('goal'));
  $('tool-draw').addEventListener('click', () => setTool('draw'));
  $('tool-edit').addEventListener('click', () => setTool('edit'));

  function updateObstacleButtons() {
    $('obstacle-finish').disabled = !(tool === 'draw' && draft.length >= 3);
    $('obstacle-save').disabled = !(selected && selected.changed);
    $('obstacle-delete').disabled = !selected;
  }

  function mapPoint(event) {
    const canvas = $('map');
    const rect = canvas.getBoundingClientRect();
    const sx = (event.clientX - rect.left) * canvas.width / rect.width;
    const sy = (event.clientY - rect.top) * canvas.height / rect.height;
    return { sx, sy, world: toWorld(sx, sy) };
  }

  function nearestVertex(sx, sy) {
    if (!selected) return -1;
    let best = -1;
    let bestDistance = 10;   // px
    selected.points.forEach((p, i) => {
      const [px, py] = toScreen(p);
      const d = Math.hypot(px - sx, py - sy);
      if (d < bestDistance) {
        best = i;
        bestDistance = d;
      }
    });
    return best;
  }

  function obstacleAt(world) {
    const [x, y] = world;
    const tolerance = 8 / view.scale;   // m
    for (const obstacle of state.obstacles) {
      const pts = obstacle.points;
      let inside = false;
      for (let i = 0, j = pts.length - 1; i < pts.length; j = i++) {
        const [xi, yi] = pts[i];
        const [xj, yj] = pts[j];
        if ((yi > y) !== (yj > y) && x < (xj - xi) * (y - yi) / (yj - yi) + xi) inside = !inside;
        if (i > 0 || obstacle.closed) {
          const dx = xj - xi;
          const dy = yj - yi;
          const t = Math.max(0, Math.min(1, ((x - xi) * dx + (y - yi) * dy) / (dx * dx + dy * dy || 1)));
          if (Math.hypot(x - xi - t * dx, y - yi - t * dy) < tolerance) return obstacle;
        }
      }
      if (inside && obstacle.closed) return obstacle;
    }
    return null;
  }

  const canvasMap = $('map');
  canvasMap.addEventListener('contextmenu', (event) => event.preventDefault());
  canvasMap.addEventListener('pointerdown', (event) => {
    if (!mapInfo) return;
    const p = mapPoint(event);
    if (event.button === 2) {
      panning = { sx: p.sx, sy: p.sy, ox: view.ox, oy: view.oy };
      return;
    }
    if (tool === 'goal') {
      goal = p.world;
      sendGoal(p.world, Number($('goal-yaw').value) * Math.PI / 180);
    } else if (tool === 'draw') {
      draft.push(p.world.map((v) => Math.round(v * 100) / 100));
    } else if (tool === 'edit') {
      const vertex = nearestVertex(p.sx, p.sy);
      if (vertex >= 0) {
        dragging = vertex;
        canvasMap.setPointerCapture(event.pointerId);
      } else {
        const hit = obstacleAt(p.world);
        selected = hit ? { id: hit.id, closed: hit.closed, points: hit.points.map((q) => q.slice()), changed: false }
          : null;
      }
    }
    $('map-info').textContent = 'x ' + p.world[0].toFixed(2) + ' m, y ' + p.world[1].toFixed(2) + ' m';
    updateObstacleButtons();
    drawMap();
  });
  canvasMap.addEventListener('pointermove', (event) => {
    const p = mapPoint(event);
    if (panning) {
      view.ox = panning.ox - (p.sx - panning.sx) / view.scale;
      view.oy = panning.oy + (p.sy - panning.sy) / view.scale;
      drawMap();
    } else if (dragging !== null && selected) {
      selected.points[dragging] = p.world.map((v) => Math.round(v * 100) / 100);
      selected.changed = true;
      updateObstacleButtons();
      drawMap();
    }
  });
  canvasMap.addEventListener('pointerup', () => { dragging = null; panning = null; });
  canvasMap.addEventListener('wheel', (event) => {
    if (!mapInfo) return;
    event.preventDefault();
    const p = mapPoint(event);
    const factor = event.deltaY < 0 ? 1.25 : 0.8;
    view.scale *= factor;
    view.ox = p.world[0] - p.sx / view.scale;
    view.oy = p.world[1] + p.sy / view.scale;
    drawMap();
  }, { passive: false });

  function obstacleCommand(cmd, body) {
    command('virtual_obstacle_cmd', cmd, JSON.stringify(body));
  }
  function queryObstacles() {
    state.obstacleQueries.add(state.transId);
    command('virtual_obstacle_cmd', 'query', '');
  }
  $('obstacle-finish').addEventListener('click', () => {
    obstacleCommand('add', { id: 'console_' + Date.now().toString(36), points: draft, closed: true });
    draft = [];
    updateObstacleButtons();
    drawMap();
  });
  $('obstacle-save').addEventListener('click', () => {
    obstacleCommand('modify', { id: selected.id, points: selected.points, closed: selected.closed });
    selected.changed = false;
    updateObstacleButtons();
  });
  $('obstacle-delete').addEventListener('click', () => {
    obstacleCommand('delete', { id: selected.id });
    selected = null;
    updateObstacleButtons();
  });
  window.addEventListener('keydown', (event) => {   // Enter finishes a polygon
    if (event.key === 'Enter' && tool === 'draw' && draft.length >= 3 && !typing(event)) $('obstacle-finish').click();
  });

  let moveClient = null;
  let goalHandle = null;
  function sendGoal(world, yaw) {
    if (!moveClient || moveClient.ros !== state.ros) {
      moveClient = new ROSLIB.ActionClient({ ros: state.ros, serverName: 'move_action',
        actionName: 'inspection_robot/GeneralAction' });
    }
    if (goalHandle) goalHandle.cancel();
    const data = { with_direction: 1, precision: 0, move_style: 0,
      goal_pose: { position: { x: world[0], y: world[1], z: 0 },
        orientation: { x: 0, y: 0, z: Math.sin(yaw / 2), w: Math.cos(yaw / 2) } } };
    const handle = new ROSLIB.Goal({ actionClient: moveClient,
      goalMessage: Object.assign(header(), { type: 'move', data: JSON.stringify(data) }) });
    handle.on('feedback', (fb) => {
      if (fb.event_code !== '2') log('move_action feedback ' + fb.event_code + ': ' + fb.data);
    });
    handle.on('result', (result) => {
      log('move_action result ' + result.ret_code + ': ' + result.data, result.ret_code !== '0');
      if (goalHandle === handle) goalHandle = null;
    });
    handle.send();
    goalHandle = handle;
    log('goal sent: x ' + world[0].toFixed(2) + ', y ' + world[1].toFixed(2) + ', heading '
      + (yaw * 180 / Math.PI).toFixed(0) + '°');
  }
  $('goal-cancel').addEventListener('click', () => {
    if (goalHandle) {
      goalHandle.cancel();
      log('goal cancel requested');
    }
    goal = null;
    drawMap();
  });

  // ------------------------------------------------------------------ presets
  $('preset-form').addEventListener('submit', (event) => {
    event.preventDefault();
    topic('preset_scale_cmd', 'inspection_robot/PresetScaleCmd').publish(new ROSLIB.Message(Object.assign(header(), {
      preset_id: $('preset-id').value, infrared: $('preset-infrared').checked, type: '', extra_data: '' })));
    $('preset-result').textContent = 'recording…';
  });
  function onPresetAck(msg) {
    const ok = msg.result === 'success';
    $('preset-result').textContent = ok ? 'recorded: ' + msg.directory : 'failed: ' + msg.directory;
    $('preset-result').className = ok ? '' : 'error';
    log('preset_scale_ack #' + msg.trans_id + ' ' + msg.result + ': ' + msg.directory, !ok);
    if (ok) loadCalibration(msg.directory);   // the calibration editor opens the new recording
  }

  // ------------------------------------------------------------------ ControlService calls
  const services = {};
  /** One ControlService request; resolves with the reply's data on `success`, rejects with the robot's
      own failure text otherwise. ``quiet`` keeps bulky successful replies (file chunks) out of the log. */
  function control(name, cmd, data, quiet) {
    if (!services[name] || services[name].ros !== state.ros) {
      services[name] = new ROSLIB.Service({ ros: state.ros, name, serviceType: 'inspection_robot/ControlService' });
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

  const FILE_CHUNK = 196608;   // bytes per file_control read: a multiple of 3, so the base64 chunks concatenate
  const MIME = { jpg: 'image/jpeg', jpeg: 'image/jpeg', png: 'image/png' };
  const pictureCache = new Map();   // path -> Promise of a data: URL, the newest PICTURE_CACHE kept
  const PICTURE_CACHE = 60;

  /** A picture of the robot's data root as a data: URL, read through file_control in chunks. */
  function fetchPicture(path) {
    if (pictureCache.has(path)) return pictureCache.get(path);
    const mime = MIME[path.split('.').pop().toLowerCase()] || 'application/octet-stream';
    const parts = [];
    const next = (offset) => control('file_control', 'read', { path, offset, length: FILE_CHUNK }, true)
      .then((text) => {
        const chunk = JSON.parse(text);
        parts.push(chunk.data);
        return chunk.eof || !chunk.length ? 'data:' + mime + ';base64,' + parts.join('') : next(offset + chunk.length);
      });
    const promise = next(0);
    promise.catch(() => pictureCache.delete(path));   // a failure is not cached
    pictureCache.set(path, promise);
    while (pictureCache.size > PICTURE_CACHE) pictureCache.delete(pictureCache.keys().next().value);
    return promise;
  }

  function loadImage(url) {
    return new Promise((resolve, reject) => {
      const image = new Image();
      image.onload = () => resolve(image);
      image.onerror = () => reject(new Error('the picture cannot be decoded'));
      image.src = url;
    });
  }

  // ------------------------------------------------------------------ calibration (calibration_control)
  const calib = { preset: '', image: null, targets: [], box: null, zero: null, full: null, tool: null, drag: null };
  window.consoleCalib = { ready: () => calib.image !== null && !$('calib-picture').classList.contains('empty'),
    preset: () => calib.preset,
    size: () => (calib.image ? [calib.image.width, calib.image.height] : null) };

  function calibMessage(text, failed) {
    $('calib-result').textContent = text;
    $('calib-result').className = failed ? 'error' : '';
  }

  function loadCalibration(preset) {
    calib.preset = '';
    calib.image = null;
    calib.box = calib.zero = calib.full = null;
    calibMessage('loading ' + preset + '…');
    return control('calibration_control', 'get', { preset }).then((text) => {
      const answer = JSON.parse(text);
      calib.targets = answer.targets;
      $('calib-preset').value = answer.preset;
      return fetchPicture(answer.preset + '/zoom0.jpg').then(loadImage).then((image) => {
        calib.image = image;
        calib.preset = answer.preset;
        const canvas = $('calib-picture');
        canvas.width = image.width;
        canvas.height = image.height;
        calibMessage(answer.preset + ': ' + (answer.calibrated ? answer.targets.length + ' target(s) calibrated'
          : 'not calibrated') + ', draft of ' + answer.draft.length + ' target(s)');
        drawCalib();
      });
    }).catch((err) => {
      calibMessage('cannot load ' + preset + ': ' + err.message, true);
      drawCalib();   // no stale picture under a failed load
    });
  }

  let calibFrame = 0;
  function drawCalib() {
    if (!calibFrame) calibFrame = requestAnimationFrame(renderCalib);
  }

  function renderCalib() {
    calibFrame = 0;
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
        parts.push(name + ' ' + RobotDecode.needleAngle(calib.box, p).toFixed(1) + '°');
      }
      parts.unshift('box ' + Math.round(x1 - x0) + '×' + Math.round(y1 - y0) + ' px');
    }
    $('calib-geometry').textContent = parts.join(', ');
  }

  function setCalibTool(name) {
    calib.tool = calib.tool === name ? null : name;
    document.querySelectorAll('.calib-tool').forEach((b) => b.classList.toggle('active', b.id === 'calib-tool-' + calib.tool));
  }
  $('calib-tool-box').addEventListener('click', () => setCalibTool('box'));
  $('calib-tool-zero').addEventListener('click', () => setCalibTool('zero'));
  $('calib-tool-full').addEventListener('click', () => setCalibTool('full'));

  function picturePoint(event) {
    const canvas = $('calib-picture');
    const rect = canvas.getBoundingClientRect();
    return [(event.clientX - rect.left) * canvas.width / rect.width, (event.clientY - rect.top) * canvas.height / rect.height];
  }
  const calibCanvas = $('calib-picture');
  calibCanvas.addEventListener('pointerdown', (event) => {
    if (!calib.image) return;
    const p = picturePoint(event);
    if (calib.tool === 'box') {
      calib.drag = p;
      calib.box = [p[0], p[1], p[0], p[1]];
      calib.zero = calib.full = null;   // angles are about the box centre: a new box needs new points
      calibCanvas.setPointerCapture(event.pointerId);
    } else if ((calib.tool === 'zero' || calib.tool === 'full') && calib.box) {
      calib[calib.tool] = p;
    }
    drawCalib();
  });
  calibCanvas.addEventListener('pointermove', (event) => {
    if (!calib.drag) return;
    const p = picturePoint(event);
    const [ax, ay] = calib.drag;
    calib.box = [Math.min(ax, p[0]), Math.min(ay, p[1]), Math.max(ax, p[0]), Math.max(ay, p[1])];
    drawCalib();
  });
  calibCanvas.addEventListener('pointerup', () => { calib.drag = null; });

  $('calib-load').addEventListener('click', () => loadCalibration($('calib-preset').value.trim()));
  $('calib-choose').addEventListener('focus', listPresets);
  $('calib-choose').addEventListener('change', () => {
    const folder = $('calib-choose').value;
    if (!folder) return;
    // The newest recording of that preset id (recordings are named YYYYMMDD_HHMMSS).
    control('file_control', 'list', { path: folder }, true).then((text) => {
      const dirs = JSON.parse(text).entries.filter((e) => e.type === 'dir');
      if (!dirs.length) throw new Error('no recording in ' + folder);
      return loadCalibration(folder + '/' + dirs[dirs.length - 1].name);
    }).catch((err) => calibMessage(err.message, true));
  });

  function listPresets() {
    control('file_control', 'list', { path: 'presets' }, true).then((text) => {
      const answer = JSON.parse(text);
      const select = $('calib-choose');
      while (select.options.length > 1) select.remove(1);
      answer.entries.filter((e) => e.type === 'dir').forEach((e) => select.add(new Option(e.name, answer.path + '/' + e.name)));
    }).catch(() => {});
  }

  $('calib-form').addEventListener('submit', (event) => {
    event.preventDefault();
    if (!calib.preset) {
      calibMessage('load a preset first', true);
      return;
    }
    if (!calib.box || calib.box[2] - calib.box[0] < 4 || calib.box[3] - calib.box[1] < 4) {
      calibMessage('draw the meter box on the picture first', true);
      return;
    }
    const kind = $('calib-kind').value;
    const preset = calib.preset;
    const target = Number($('calib-target').value);
    const [x0, y0, x1, y1] = calib.box;
    const steps = [['mark_box', { box: RobotDecode.boxQuad(calib.box) }], ['set_meter_type', { kind }]];
    if (kind === 'pointer') {
      if (!calib.zero || !calib.full) {
        calibMessage('click the needle\'s zero and full-scale points first', true);
        return;
      }
      const angle = (p) => Math.round(RobotDecode.needleAngle(calib.box, p) * 10) / 10;
      steps.push(['set_zero', { angle: angle(calib.zero), value: Number($('calib-zero-value').value) }],
        ['set_full_scale', { angle: angle(calib.full), value: Number($('calib-full-value').value) }],
        ['set_values', { values: { centre: [0.5, 0.5], aspect: Math.round((x1 - x0) / (y1 - y0) * 1000) / 1000 } }]);
    }
    const values = {};
    if ($('calib-name').value) values.name = $('calib-name').value;
    if ($('calib-unit').value && kind === 'pointer') values.unit = $('calib-unit').value;   // a pointer key only
    if (Object.keys(values).length) steps.push(['set_values', { values }]);
    calibMessage('applying…');
    // One edit after the other, then apply: the first refusal stops the chain with the robot's text.
    steps.reduce((chain, [cmd, fields]) => chain.then(() => control('calibration_control', cmd,
      Object.assign({ preset, target }, fields))), Promise.resolve())
      .then((lastEdit) => {
        // the robot reads the picture itself; with the value the operator sees it refuses a wrong calibration
        const apply = { preset };
        const shown = $('calib-expected').value;
        if (shown !== '' && kind === 'pointer') {
          apply.expected = JSON.parse(lastEdit).draft.map((_t, i) => (i === target ? Number(shown) : null));
        }
        if ($('calib-force').checked) apply.force = true;
        return control('calibration_control', 'apply', apply);
      })
      .then((text) => {
        const answer = JSON.parse(text);
        const checks = (answer.self_check || []).filter((c) => c.target === target).map(RobotDecode.selfCheckText);
        calibMessage('applied: ' + answer.targets + ' target(s) (' + answer.kinds.join(', ') + ')' +
          (checks.length ? '; ' + checks.join('; ') : ''));
        return control('calibration_control', 'get', { preset }).then((got) => {
          calib.targets = JSON.parse(got).targets;
          drawCalib();
        });
      })
      .catch((err) => calibMessage('refused: ' + err.message, true));
  });

  // ------------------------------------------------------------------ patrol and history (task_manager)
  const MAX_RESULT_ROWS = 200;
  const MAX_RESULT_PICTURES = 30;
  // ``follow``: the readings follow the running (or last) task until the operator types a task id.
  const patrol = { status: null, frame: 0, follow: true, resultsKey: '', querying: false, again: false };
  window.consolePatrol = { status: () => patrol.status };

  function exampleTask() {
    const stamp = new Date().toISOString().replace(/[-:]/g, '').replace('T', '_').slice(0, 15);
    return JSON.stringify({ id: 'patrol_' + stamp, priority: 'routine', retries: 1, stops: [
      { name: 'cabinet_1', pose: { x: 20.0, y: 21.4, yaw: 1.5708 }, precision: 0,
        presets: [{ preset: 'cabinet_1', alarms: {}, foreign: false }] }] }, null, 2);
  }
  $('patrol-task').value = exampleTask();

  function patrolCommand(cmd, data) {
    $('patrol-result').textContent = cmd + '…';
    $('patrol-result').className = '';
    return control('task_control', cmd, data).then(() => {
      $('patrol-result').textContent = cmd + ': done';
    }).catch((err) => {
      $('patrol-result').textContent = cmd + ' refused: ' + err.message;
      $('patrol-result').className = 'error';
    });
  }
  $('patrol-form').addEventListener('submit', (event) => {
    event.preventDefault();
    patrolCommand('submit', $('patrol-task').value).then(() => {
      if ($('patrol-result').className !== 'error') $('patrol-task').value = exampleTask();   // ids are never reused
    });
  });
  $('patrol-pause').addEventListener('click', () => patrolCommand('pause', ''));
  $('patrol-resume').addEventListener('click', () => patrolCommand('resume', ''));
  $('patrol-cancel').addEventListener('click', () => patrolCommand('cancel', ''));
  $('patrol-home').addEventListener('click', () => patrolCommand('return_home', ''));

  function onTaskStatus(msg) {
    try {
      patrol.status = JSON.parse(msg.data);
    } catch (err) {
      log('task_status unreadable: ' + err, true);
      return;
    }
    if (!patrol.frame) patrol.frame = requestAnimationFrame(renderPatrol);
  }

  function renderPatrol() {
    patrol.frame = 0;
    const s = patrol.status;
    const parts = [s.state + (s.task_id ? ': ' + s.task_id + (s.priority ? ' (' + s.priority + ')' : '') : '')];
    if (s.task_id && s.stops) {
      parts.push('stop ' + s.stop + ' of ' + s.stops + (s.stop_name ? ' (' + s.stop_name + ')' : ''),
        'preset ' + s.preset + ' of ' + s.presets, s.done + '/' + s.total + ' presets done',
        'ETA ' + Math.round(s.eta_s || 0) + ' s');
    }
    if (s.holds && s.holds.length) parts.push('held: ' + s.holds.join(', '));
    if (s.suspended) parts.push('suspended: ' + s.suspended);
    if (s.reason) parts.push(s.reason);
    if (s.last_ended) parts.push('last ended: ' + s.last_ended.task_id + ' ' + s.last_ended.state
      + (s.last_ended.reason ? ' (' + s.last_ended.reason + ')' : ''));
    $('patrol-state').textContent = parts.join(' · ');
    $('patrol-state').className = s.holds && s.holds.length ? 'error' : '';
    $('patrol-progress').max = Math.max(1, s.total || 0);
    $('patrol-progress').value = s.done || 0;
    // Follow the running (or last) task's readings unless the operator typed another task id.
    const task = s.task_id || (s.last_ended && s.last_ended.task_id) || '';
    const input = $('results-task');
    if (task && patrol.follow) input.value = task;
    const key = task + '|' + s.done + '|' + s.state;
    if (task && patrol.follow && key !== patrol.resultsKey) {
      patrol.resultsKey = key;
      queryResults();
    }
    if (key !== review.key) {   // a preset recorded (or the page just connected): the queue may have grown
      review.key = key;
      queryReview();
    }
  }

  $('results-refresh').addEventListener('click', queryResults);
  $('results-task').addEventListener('input', () => { patrol.follow = $('results-task').value.trim() === ''; });

  function queryResults() {
    const task = $('results-task').value.trim();
    if (patrol.querying) {
      patrol.again = true;   // one more query when this one is back, not one per status
      return;
    }
    patrol.querying = true;
    control('task_control', 'query_results', task ? { task_id: task, limit: 5000 } : { limit: 500 }, true)
      .then((text) => renderResults(JSON.parse(text)))
      .catch((err) => { $('results-count').textContent = 'query refused: ' + err.message; })
      .then(() => {
        patrol.querying = false;
        if (patrol.again) {
          patrol.again = false;
          queryResults();
        }
      });
  }

  /** Alarms first, then failures, then the rest; newest first within each (bounded to MAX_RESULT_ROWS). */
  function renderResults(rows) {
    const shown = RobotDecode.sortReadings(rows).slice(0, MAX_RESULT_ROWS);
    const alarms = rows.filter((r) => r.alarm === 'alarm').length;
    $('results-count').textContent = rows.length + ' reading(s), ' + alarms + ' alarm(s)'
      + (shown.length < rows.length ? ', first ' + shown.length + ' shown' : '');
    const body = $('results').tBodies[0];
    const fresh = document.createElement('tbody');
    shown.forEach((r, i) => {
      const tr = fresh.insertRow();
      tr.className = r.alarm === 'alarm' || r.alarm === 'check' ? r.alarm : r.status === 'failed' ? 'failed' : '';
      tr.insertCell().textContent = r.alarm;
      const target = tr.insertCell();
      target.textContent = r.target_name || r.kind + ' ' + r.target;
      if (r.target_name) {
        target.className = 'trend-link';
        target.title = 'show this meter\'s trend';
        target.addEventListener('click', () => showTrend(r.target_name, r.unit));
      }
      tr.insertCell().textContent = RobotDecode.readingText(r);
      tr.insertCell().textContent = r.stop_name || String(r.stop + 1);
      tr.insertCell().textContent = new Date(r.time * 1000).toLocaleString();
      const cell = tr.insertCell();
      if (r.picture && i < MAX_RESULT_PICTURES) {
        const img = document.createElement('img');
        img.alt = r.picture;
        cell.appendChild(img);
        fetchPicture(r.picture).then((url) => { img.src = url; })
          .catch((err) => { cell.textContent = 'picture: ' + err.message; });
      } else if (r.picture) {
        cell.textContent = r.picture.split('/').pop();
      }
    });
    body.parentNode.replaceChild(fresh, body);
  }

  // ------------------------------------------------------------------ a meter's trend
  const TREND_DAYS = 90;
  const TREND_COLOURS = { read: '#2e7d32', uncertain: '#e65100', corrected: '#1565c0', alarm: '#c62828',
    check: '#e65100', trend: '#6a1b9a' };

  function showTrend(target, unit) {
    $('trend-meter').textContent = target + ' (loading…)';
    const since = Date.now() / 1000 - TREND_DAYS * 86400;
    control('task_control', 'query_results', { target, from: since, limit: 5000 }, true)
      .then((text) => drawTrend($('trend'), target, unit, JSON.parse(text)))
      .catch((err) => { $('trend-meter').textContent = target + ': query refused: ' + err.message; });
  }

  function drawTrend(canvas, target, unit, rows) {
    const series = RobotDecode.trendSeries(rows);
    const ctx = canvas.getContext('2d');
    const w = canvas.width;
    const h = canvas.height;
    const pad = 36;
    ctx.fillStyle = '#fff';
    ctx.fillRect(0, 0, w, h);
    const times = series.points.map((p) => p.t);
    const t0 = Math.min.apply(null, times.length ? times : [0]);
    const t1 = Math.max.apply(null, times.length ? times : [1]);
    const x = (t) => pad + (t1 > t0 ? (t - t0) / (t1 - t0) : 0.5) * (w - 2 * pad);
    const [lo, hi] = series.range;
    const y = (v) => h - pad - (v - lo) / (hi - lo) * (h - 2 * pad);
    if (series.band) {   // the normal band, shaded
      ctx.fillStyle = 'rgba(46, 125, 50, 0.12)';
      ctx.fillRect(pad, y(series.band[1]), w - 2 * pad, y(series.band[0]) - y(series.band[1]));
    }
    ctx.strokeStyle = '#999';
    ctx.strokeRect(pad, pad, w - 2 * pad, h - 2 * pad);
    ctx.fillStyle = '#333';
    ctx.font = '11px sans-serif';
    ctx.fillText(hi.toPrecision(4) + (unit ? ' ' + unit : ''), 2, pad);
    ctx.fillText(lo.toPrecision(4), 2, h - pad);
    if (times.length) {
      ctx.fillText(new Date(t0 * 1000).toLocaleDateString(), pad, h - 8);
      ctx.fillText(new Date(t1 * 1000).toLocaleDateString(), w - pad - 70, h - 8);
    }
    ctx.strokeStyle = '#777';
    ctx.beginPath();
    series.points.forEach((p, i) => (i ? ctx.lineTo(x(p.t), y(p.v)) : ctx.moveTo(x(p.t), y(p.v))));
    ctx.stroke();
    series.points.forEach((p) => {
      ctx.fillStyle = TREND_COLOURS[p.kind] || '#333';
      ctx.beginPath();
      ctx.arc(x(p.t), y(p.v), 3.5, 0, 2 * Math.PI);
      ctx.fill();
      if (p.kind === 'trend') {
        ctx.strokeStyle = TREND_COLOURS.trend;
        ctx.beginPath();
        ctx.arc(x(p.t), y(p.v), 7, 0, 2 * Math.PI);
        ctx.stroke();
      }
    });
    canvas.dataset.points = String(series.points.length);
    $('trend-meter').textContent = target + ': ' + series.points.length + ' reading(s) in ' + TREND_DAYS + ' days';
  }

  // ------------------------------------------------------------------ review of uncertain readings
  const REVIEW_LIMIT = 20;
  const review = { key: null, querying: false, again: false };
  window.consoleReview = { ids: () => Array.from(document.querySelectorAll('.review-item'), (e) => Number(e.dataset.id)) };

  function reviewMessage(text, failed) {
    $('review-result').textContent = text;
    $('review-result').className = failed ? 'error' : '';
  }

  function queryReview() {
    if (review.querying) {
      review.again = true;
      return;
    }
    review.querying = true;
    control('task_control', 'review_queue', { limit: REVIEW_LIMIT }, true)
      .then((text) => renderReview(JSON.parse(text)))
      .catch((err) => reviewMessage('review queue refused: ' + err.message, true))
      .then(() => {
        review.querying = false;
        if (review.again) {
          review.again = false;
          queryReview();
        }
      });
  }
  $('review-refresh').addEventListener('click', queryReview);

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
          .catch((err) => { figure.textContent = 'picture: ' + err.message; });
      } else {
        figure.textContent = 'no picture';
      }
      const text = document.createElement('div');
      text.className = 'review-text';
      const what = document.createElement('div');
      what.textContent = (r.target_name || r.kind + ' ' + r.target) + ' · ' + r.task_id + ' stop ' + (r.stop + 1)
        + (r.stop_name ? ' (' + r.stop_name + ')' : '') + ' · ' + new Date(r.time * 1000).toLocaleString();
      const value = document.createElement('div');
      value.className = r.alarm === 'check' ? 'check' : '';
      value.textContent = 'robot: ' + RobotDecode.readingText(r) + ' (confidence ' + r.confidence + ')'
        + (r.alarm === 'check' ? ' · CHECK: outside its band' : '');
      const form = document.createElement('form');
      form.className = 'row';
      const input = document.createElement('input');
      input.type = 'number';
      input.step = 'any';
      input.required = true;
      input.className = 'review-value';
      input.placeholder = 'true value';
      const correct = document.createElement('button');
      correct.type = 'submit';
      correct.className = 'review-correct';
      correct.textContent = 'correct';
      const confirm = document.createElement('button');
      confirm.type = 'button';
      confirm.className = 'review-confirm';
      confirm.textContent = 'confirm ' + Number(r.value.toPrecision(4)) + (r.unit ? ' ' + r.unit : '');
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
    list.parentNode.replaceChild(fresh, list);
  }

  /** review one reading: ``value`` the true value, or null to confirm the robot's. */
  function settle(row, value, item) {
    const by = $('review-by').value.trim();
    if (!by) {
      reviewMessage('type your name in "reviewer" first', true);
      $('review-by').focus();
      return;
    }
    if (value !== null && !Number.isFinite(value)) {
      reviewMessage('the true value must be a number', true);
      return;
    }
    item.querySelectorAll('button, input').forEach((e) => { e.disabled = true; });
    control('task_control', 'review', { id: row.id, value, by })
      .then((text) => {
        const done = JSON.parse(text);
        reviewMessage('reading ' + done.id + ' (' + done.target_name + '): '
          + (value === null ? 'confirmed' : 'corrected to ' + done.review_value) + ' by ' + done.review_by);
        queryReview();
        if ($('results-task').value.trim() === row.task_id) queryResults();
      })
      .catch((err) => {
        reviewMessage('review refused: ' + err.message, true);
        item.querySelectorAll('button, input').forEach((e) => { e.disabled = false; });
      });
  }

  // ------------------------------------------------------------------ start
  fetch('config.json', { cache: 'no-store' })
    .then((response) => response.json())
    .then((config) => { state.authRequired = !!config.auth_required; })
    .catch(() => log('config.json unreadable: assuming no authentication', true))
    .then(connect);
}());
