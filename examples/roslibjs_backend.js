#!/usr/bin/env node
/*
 * A backend's first session with the robot over its websocket, with roslibjs (npm `roslib` 1.x) in
 * Node. The same steps as roslibpy_backend.py (docs/interface.md, "Clients"):
 *   1. connect, draw a session number and send the heartbeat under it (server_status, trans_id =
 *      the session, every 0.5 s) until the end;
 *   2. wait for robot_status to answer *its own* heartbeat (offline_warn 0 and trans_id = the
 *      session): a backend that reconnects would otherwise see the previous one's heartbeat;
 *   3. take the robot (mode_cmd acquire server with trans_id = the session, answered on mode_ack:
 *      granted on this session's heartbeat only) and drive it a little with
 *      move_cmd (0.3 m/s for 1.5 s at 10 Hz: the robot stops 0.5 s after the last one);
 *   4. give it back to task mode (mode_cmd release): move_base drives only in task mode;
 *   5. drive to a goal as an action goal (move_action, ROSLIB.ActionClient = ROS 1 actionlib);
 *   6. read task_status, export the results store (task_control export_results) and stat the
 *      snapshot over file_control.
 * One line per step; exit code 0 when every step succeeded, 1 otherwise.
 *
 *   npm install roslib@1          # brings `ws`, the WebSocket roslib uses in Node
 *   node roslibjs_backend.js --host 127.0.0.1 --port 9090 --goal 7.0,5.0,0.0
 *
 * In this repository: NODE_PATH=web/node_modules node examples/roslibjs_backend.js --port 9090
 */
'use strict';
const crypto = require('crypto');
const ROSLIB = require('roslib');

function option(name, fallback) {
  const at = process.argv.indexOf('--' + name);
  return at >= 0 && at + 1 < process.argv.length ? process.argv[at + 1] : fallback;
}

/** Resolves with predicate()'s first truthy value, checked on every message; rejects after timeoutS. */
function waitFor(state, predicate, timeoutS, what) {
  return new Promise((resolve, reject) => {
    const check = () => {
      const value = predicate();
      if (!value) return false;
      clearTimeout(timer);
      state.waiters.delete(check);
      resolve(value);
      return true;
    };
    const timer = setTimeout(() => {
      state.waiters.delete(check);
      reject(new Error('timed out after ' + timeoutS + ' s waiting for ' + what));
    }, timeoutS * 1000);
    if (!check()) state.waiters.add(check);
  });
}

async function main() {
  const host = option('host', '127.0.0.1');
  const port = Number(option('port', '9090'));
  const [x, y, yaw] = option('goal', '7.0,5.0,0.0').split(',').map(Number);
  const ros = new ROSLIB.Ros({ url: 'ws://' + host + ':' + port });
  await new Promise((resolve, reject) => {
    ros.on('connection', resolve);
    ros.on('error', (err) => reject(new Error('cannot connect: ' + (err.message || err))));
  });
  console.log('roslibjs: connected to ' + host + ':' + port);

  const state = { robot: null, task: null, acks: new Map(), waiters: new Set(), transId: 0 };
  const changed = () => state.waiters.forEach((check) => check());
  new ROSLIB.Topic({ ros, name: 'robot_status', messageType: 'inspection_robot/RobotStatus', throttle_rate: 200 })
    .subscribe((m) => { state.robot = m; changed(); });
  new ROSLIB.Topic({ ros, name: 'task_status', messageType: 'inspection_robot/GeneralTopic' })
    .subscribe((m) => { state.task = JSON.parse(m.data); changed(); });
  new ROSLIB.Topic({ ros, name: 'mode_ack', messageType: 'inspection_robot/GeneralAck' })
    .subscribe((m) => { state.acks.set(m.trans_id, m); changed(); });
  const modeCmd = new ROSLIB.Topic({ ros, name: 'mode_cmd', messageType: 'inspection_robot/GeneralCmd' });
  const moveCmd = new ROSLIB.Topic({ ros, name: 'move_cmd', messageType: 'inspection_robot/MoveCmd' });
  const heartbeat = new ROSLIB.Topic({ ros, name: 'server_status', messageType: 'inspection_robot/GeneralTopic' });
  const session = crypto.randomBytes(4).readUInt32BE(0) || 1;   // names this connection's heartbeat
  const beat = setInterval(() => heartbeat.publish(new ROSLIB.Message({ sender: 'server', trans_id: session, data: '' })),
    500);
  const online = () => state.robot && state.robot.offline_warn === 0 && state.robot.trans_id === session;

  const mode = async (cmd, data, sessionId) => {
    const transId = sessionId === undefined ? ++state.transId : sessionId;
    modeCmd.publish(new ROSLIB.Message({ sender: 'server', trans_id: transId, cmd, data }));
    const ack = await waitFor(state, () => state.acks.get(transId), 10, 'mode_ack of ' + cmd);
    return [ack.ack, ack.data];
  };
  const sleep = (ms) => new Promise((resolve) => setTimeout(resolve, ms));
  const drive = async (speedMmS, seconds) => {   // move_cmd at 10 Hz, then one explicit stop
    const speeds = Array(Math.round(seconds * 10)).fill(speedMmS).concat([0]);
    for (const speed of speeds) {
      moveCmd.publish(new ROSLIB.Message({ sender: 'server', trans_id: 0, velocity_x: speed, velocity_yaw: 0,
        wheel_control: 0 }));
      await sleep(100);
    }
  };
  const pose = () => '(' + state.robot.position.slice(0, 2).map((v) => v.toFixed(2)).join(', ') + ')';
  const control = (service, cmd, data) => new Promise((resolve, reject) => {
    const srv = new ROSLIB.Service({ ros, name: service, serviceType: 'inspection_robot/ControlService' });
    srv.callService(new ROSLIB.ServiceRequest({ sender: 'server', trans_id: ++state.transId, cmd, data: data || '' }),
      (reply) => resolve([reply.ack, reply.data]), (err) => reject(new Error(service + ' ' + cmd + ': ' + err)));
  });
  const move = () => new Promise((resolve, reject) => {
    const client = new ROSLIB.ActionClient({ ros, serverName: 'move_action', actionName: 'inspection_robot/GeneralAction' });
    const goalPose = { position: { x, y, z: 0 }, orientation: { x: 0, y: 0, z: Math.sin(yaw / 2), w: Math.cos(yaw / 2) } };
    const goal = new ROSLIB.Goal({ actionClient: client, goalMessage: {
      sender: 'server', trans_id: 1, type: 'move',
      data: JSON.stringify({ goal_pose: goalPose, with_direction: 1, precision: 0 }) } });
    let feedbacks = 0;
    const timer = setTimeout(() => reject(new Error('move_action: no result within 120 s')), 120000);
    goal.on('feedback', () => { feedbacks += 1; });
    goal.on('result', (result) => {
      clearTimeout(timer);
      client.dispose();
      resolve([result.ret_code, JSON.parse(result.data || '{}'), feedbacks]);
    });
    goal.send();
  });

  try {
    await waitFor(state, online, 20, 'robot_status online on our heartbeat (offline_warn 0, trans_id ' + session + ')');
    console.log('online: robot_status offline_warn 0, mode ' + state.robot.mode + ', our heartbeat (session ' +
      session + ')');
    let [ack, data] = await mode('acquire', 'server', session);
    console.log('acquire server: ' + ack + ' ' + data);
    if (ack !== 'success') return 1;
    const before = pose();
    await drive(300, 1.5);
    await sleep(1000);   // braking, and robot_status catching up
    console.log('move_cmd: drove from ' + before + ' to ' + pose());
    [ack, data] = await mode('release', '');
    console.log('release: ' + ack + ' ' + data);
    const [retCode, result, feedbacks] = await move();
    console.log('move_action: ret_code ' + retCode + ', ' + feedbacks + ' feedback(s), pose ' + JSON.stringify(result.pose));
    const status = await waitFor(state, () => state.task, 20, 'task_status');
    console.log('task_status: state ' + status.state + ", task '" + status.task_id + "', " + status.done + '/'
      + status.total + ' presets done');
    [ack, data] = await control('task_control', 'export_results');
    if (ack !== 'success') {
      console.log('export_results: ' + ack + ' ' + data);
      return 1;
    }
    const path = JSON.parse(data).path;
    [ack, data] = await control('file_control', 'stat', JSON.stringify({ path }));
    const stat = ack === 'success' ? JSON.parse(data) : {};
    console.log('export_results: ' + path + ', ' + stat.size + ' bytes, sha256 ' + String(stat.sha256 || data).slice(0, 12));
    return retCode === '0' && ack === 'success' ? 0 : 1;
  } finally {
    clearInterval(beat);
    ros.close();
  }
}

main().then((code) => process.exit(code), (err) => {
  console.log('error: ' + err.message);
  process.exit(1);
});
