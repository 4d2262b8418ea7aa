/* The map panel: the occupancy map, the robot's pose and move_base's plan; goals sent with move_action;
   virtual obstacles drawn, edited and deleted (virtual_obstacle_cmd). Wheel zooms, right-drag pans. */
import { t } from './i18n.js';
import { actionClient, command, header, nextTransId, onAck, subscribe } from './link.js';
import * as store from './state.js';
import { $, canvasPoint, log, typing } from './ui.js';

const view = { scale: 0, ox: 0, oy: 0 };   // screen = (world - origin) * scale, y up
const map = { image: null, info: null, plan: null, tool: null, draft: [], selected: null, dragging: null,
  panning: null, goal: null, obstacles: [], frame: 0, moveClient: null, goalHandle: null };
const obstacleQueries = new Set();   // trans_ids of the page's own pending `query` commands
const layers = [];   // other panels' drawings over the map: draw(ctx, toScreen)
const pickHandlers = {};   // tool name -> handler(world [x, y], tolerance m) of another panel's map tool
const PICK_TOLERANCE_PX = 12;

export const toScreen = ([x, y]) => [(x - view.ox) * view.scale, (view.oy - y) * view.scale];
const toWorld = (sx, sy) => [sx / view.scale + view.ox, view.oy - sy / view.scale];

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
  map.image = document.createElement('canvas');
  map.image.width = info.width;
  map.image.height = info.height;
  map.image.getContext('2d').putImageData(image, 0, 0);
  map.info = info;
  fitMap();
  drawMap();
}

function onPlan(msg) {
  map.plan = msg.poses.map((p) => [p.pose.position.x, p.pose.position.y]);
  drawMap();
}

function fitMap() {
  const canvas = $('map');
  const w = map.info.width * map.info.resolution;
  const h = map.info.height * map.info.resolution;
  view.scale = Math.min(canvas.width / w, canvas.height / h);
  view.ox = map.info.origin.position.x;
  view.oy = map.info.origin.position.y + canvas.height / view.scale;
}

function polyline(ctx, points, closed) {
  ctx.beginPath();
  points.forEach((p, i) => {
    const [sx, sy] = toScreen(p);
    if (i) ctx.lineTo(sx, sy); else ctx.moveTo(sx, sy);
  });
  if (closed) ctx.closePath();
}

/** Redraw on the next animation frame (at most once per frame). */
export function drawMap() {
  if (!map.frame) map.frame = requestAnimationFrame(renderMap);
}

function renderMap() {
  map.frame = 0;
  const canvas = $('map');
  const ctx = canvas.getContext('2d');
  ctx.setTransform(1, 0, 0, 1, 0, 0);
  ctx.fillStyle = '#9e9e9e';
  ctx.fillRect(0, 0, canvas.width, canvas.height);
  if (!map.info) return;
  const [mx, my] = toScreen([map.info.origin.position.x, map.info.origin.position.y]);
  const mw = map.info.width * map.info.resolution * view.scale;
  const mh = map.info.height * map.info.resolution * view.scale;
  ctx.imageSmoothingEnabled = false;
  ctx.drawImage(map.image, mx, my - mh, mw, mh);
  const selected = map.selected;
  for (const obstacle of map.obstacles) {
    const mine = selected && selected.id === obstacle.id;
    const points = mine ? selected.points : obstacle.points;
    ctx.strokeStyle = mine ? '#ff6d00' : '#d50000';
    ctx.lineWidth = 3;
    polyline(ctx, points, obstacle.closed);
    ctx.stroke();
    if (mine) {
      ctx.fillStyle = '#ff6d00';
      for (const p of points) {
        const [sx, sy] = toScreen(p);
        ctx.fillRect(sx - 4, sy - 4, 8, 8);
      }
    }
  }
  if (map.draft.length) {
    ctx.strokeStyle = '#d50000';
    ctx.setLineDash([6, 4]);
    polyline(ctx, map.draft, map.draft.length > 2);
    ctx.stroke();
    ctx.setLineDash([]);
  }
  if (map.plan && map.plan.length) {
    ctx.strokeStyle = '#1565c0';
    ctx.lineWidth = 2;
    polyline(ctx, map.plan, false);
    ctx.stroke();
  }
  layers.forEach((draw) => draw(ctx, toScreen));
  if (map.goal) {
    const [gx, gy] = toScreen(map.goal);
    ctx.strokeStyle = '#2e7d32';
    ctx.beginPath();
    ctx.arc(gx, gy, 7, 0, 2 * Math.PI);
    ctx.stroke();
  }
  const s = store.get('status');
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

/** Draw ``draw(ctx, toScreen)`` over the map (under the goal and the robot) on every redraw. */
export function addLayer(draw) {
  layers.push(draw);
}

/** A map tool of another panel: while its button (id ``tool-<name>``, class ``tool``) is active, a
    click on the map calls ``handler(world [x, y], tolerance m)``. Returns the function that toggles it. */
export function addTool(name, handler) {
  pickHandlers[name] = handler;
  return () => setTool(name);
}

function setTool(name) {
  map.tool = map.tool === name ? null : name;
  map.draft = [];
  if (map.tool !== 'edit') map.selected = null;
  document.querySelectorAll('.tool').forEach((b) => b.classList.toggle('active', b.id === 'tool-' + map.tool));
  updateObstacleButtons();
  drawMap();
}

function updateObstacleButtons() {
  $('obstacle-finish').disabled = !(map.tool === 'draw' && map.draft.length >= 3);
  $('obstacle-save').disabled = !(map.selected && map.selected.changed);
  $('obstacle-delete').disabled = !map.selected;
}

function mapPoint(event) {
  const [sx, sy] = canvasPoint($('map'), event);
  return { sx, sy, world: toWorld(sx, sy) };
}

function nearestVertex(sx, sy) {
  if (!map.selected) return -1;
  let best = -1;
  let bestDistance = 10;   // px
  map.selected.points.forEach((p, i) => {
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
  for (const obstacle of map.obstacles) {
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

const round1cm = (p) => p.map((v) => Math.round(v * 100) / 100);

function onPointerDown(event) {
  if (!map.info) return;
  const canvas = $('map');
  const p = mapPoint(event);
  if (event.button === 2) {
    map.panning = { sx: p.sx, sy: p.sy, ox: view.ox, oy: view.oy };
    return;
  }
  if (map.tool === 'goal') {
    map.goal = p.world;
    sendGoal(p.world, Number($('goal-yaw').value) * Math.PI / 180);
  } else if (pickHandlers[map.tool]) {
    pickHandlers[map.tool](p.world, PICK_TOLERANCE_PX / view.scale);
  } else if (map.tool === 'draw') {
    map.draft.push(round1cm(p.world));
  } else if (map.tool === 'edit') {
    const vertex = nearestVertex(p.sx, p.sy);
    if (vertex >= 0) {
      map.dragging = vertex;
      canvas.setPointerCapture(event.pointerId);
    } else {
      const hit = obstacleAt(p.world);
      map.selected = hit ? { id: hit.id, closed: hit.closed, points: hit.points.map((q) => q.slice()), changed: false }
        : null;
    }
  }
  $('map-info').textContent = 'x ' + p.world[0].toFixed(2) + ' m, y ' + p.world[1].toFixed(2) + ' m';
  updateObstacleButtons();
  drawMap();
}

function onPointerMove(event) {
  const p = mapPoint(event);
  if (map.panning) {
    view.ox = map.panning.ox - (p.sx - map.panning.sx) / view.scale;
    view.oy = map.panning.oy + (p.sy - map.panning.sy) / view.scale;
    drawMap();
  } else if (map.dragging !== null && map.selected) {
    map.selected.points[map.dragging] = round1cm(p.world);
    map.selected.changed = true;
    updateObstacleButtons();
    drawMap();
  }
}

function onWheel(event) {
  if (!map.info) return;
  event.preventDefault();
  const p = mapPoint(event);
  view.scale *= event.deltaY < 0 ? 1.25 : 0.8;
  view.ox = p.world[0] - p.sx / view.scale;
  view.oy = p.world[1] + p.sy / view.scale;
  drawMap();
}

function obstacleCommand(cmd, body) {
  command('virtual_obstacle_cmd', cmd, JSON.stringify(body));
}

function queryObstacles() {
  obstacleQueries.add(nextTransId());
  command('virtual_obstacle_cmd', 'query', '');
}

function onObstacleAck(name, msg) {
  if (name !== 'virtual_obstacle_ack' || !obstacleQueries.delete(msg.trans_id) || msg.ack !== 'success') return;
  try {
    map.obstacles = JSON.parse(msg.data);
  } catch (err) {
    log(t('virtual obstacle list unreadable') + ': ' + err, true);
  }
  drawMap();
}

function sendGoal(world, yaw) {
  map.moveClient = actionClient(map.moveClient, 'move_action', 'inspection_robot/GeneralAction');
  if (map.goalHandle) map.goalHandle.cancel();
  const data = { with_direction: 1, precision: 0, move_style: 0,
    goal_pose: { position: { x: world[0], y: world[1], z: 0 },
      orientation: { x: 0, y: 0, z: Math.sin(yaw / 2), w: Math.cos(yaw / 2) } } };
  const handle = new ROSLIB.Goal({ actionClient: map.moveClient,
    goalMessage: Object.assign(header(), { type: 'move', data: JSON.stringify(data) }) });
  handle.on('feedback', (fb) => {
    if (fb.event_code !== '2') log('move_action feedback ' + fb.event_code + ': ' + fb.data);
  });
  handle.on('result', (result) => {
    log('move_action result ' + result.ret_code + ': ' + result.data, result.ret_code !== '0');
    if (map.goalHandle === handle) map.goalHandle = null;
  });
  handle.send();
  map.goalHandle = handle;
  log(t('goal sent: x {x}, y {y}, heading {heading}°', { x: world[0].toFixed(2), y: world[1].toFixed(2),
    heading: (yaw * 180 / Math.PI).toFixed(0) }));
}

export function init() {
  // For the browser tests: the map transform and the page's obstacle list.
  window.consoleMap = { toScreen, ready: () => map.info !== null, obstacleCount: () => map.obstacles.length };
  store.on('status', drawMap);   // the robot's pose
  $('tool-goal').addEventListener('click', () => setTool('goal'));
  $('tool-draw').addEventListener('click', () => setTool('draw'));
  $('tool-edit').addEventListener('click', () => setTool('edit'));
  const canvas = $('map');
  canvas.addEventListener('contextmenu', (event) => event.preventDefault());
  canvas.addEventListener('pointerdown', onPointerDown);
  canvas.addEventListener('pointermove', onPointerMove);
  canvas.addEventListener('pointerup', () => { map.dragging = null; map.panning = null; });
  canvas.addEventListener('wheel', onWheel, { passive: false });
  $('obstacle-finish').addEventListener('click', () => {
    obstacleCommand('add', { id: 'console_' + Date.now().toString(36), points: map.draft, closed: true });
    map.draft = [];
    updateObstacleButtons();
    drawMap();
  });
  $('obstacle-save').addEventListener('click', () => {
    const selected = map.selected;
    obstacleCommand('modify', { id: selected.id, points: selected.points, closed: selected.closed });
    selected.changed = false;
    updateObstacleButtons();
  });
  $('obstacle-delete').addEventListener('click', () => {
    obstacleCommand('delete', { id: map.selected.id });
    map.selected = null;
    updateObstacleButtons();
  });
  window.addEventListener('keydown', (event) => {   // Enter finishes a polygon
    if (event.key === 'Enter' && map.tool === 'draw' && map.draft.length >= 3 && !typing(event)) {
      $('obstacle-finish').click();
    }
  });
  $('goal-cancel').addEventListener('click', () => {
    if (map.goalHandle) {
      map.goalHandle.cancel();
      log(t('goal cancel requested'));
    }
    map.goal = null;
    drawMap();
  });
  onAck(onObstacleAck);
  subscribe('map', 'nav_msgs/OccupancyGrid', { compression: 'cbor', queue_length: 1 }, onMap);
  subscribe('plan', 'nav_msgs/Path', { queue_length: 1 }, onPlan);
  // move_base republishes the virtual layer on every change (whoever made it): then ask for the list.
  subscribe('virtual_obstacle_map', 'nav_msgs/OccupancyGrid', { compression: 'cbor', queue_length: 1 }, queryObstacles);
}
