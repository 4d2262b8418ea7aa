/* The live pictures: camera/image_raw and thermal/image_raw (CBOR) drawn on canvases, the hottest
   point marked, and a click on the visible picture turning the head there (preset_rotate). */
import { publish, subscribe } from './link.js';
import { $, canvasPoint, log } from './ui.js';

let hottest = null;   // thermal/hottest: {x, y, temperature}

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
    hottest = JSON.parse(msg.data);
    $('thermal-caption').textContent = 'thermal: hottest ' + hottest.temperature.toFixed(1) + ' °C at ('
      + hottest.x + ', ' + hottest.y + ')';
  } catch (err) {
    log('thermal/hottest unreadable: ' + err, true);
  }
}

export function init() {
  window.consoleFrames = { picture: 0, thermal: 0 };   // live pictures drawn, for the browser tests
  $('picture').addEventListener('click', (event) => {
    const canvas = $('picture');
    const [x, y] = canvasPoint(canvas, event);
    publish('preset_rotate', 'inspection_robot/PresetRotate', { width: canvas.width, height: canvas.height,
      delta_x: Math.round(x - canvas.width / 2), delta_y: Math.round(canvas.height / 2 - y) });
  });
  subscribe('camera/image_raw', 'sensor_msgs/Image', { compression: 'cbor', queue_length: 1 },
    (msg) => drawImage($('picture'), msg));
  subscribe('thermal/image_raw', 'sensor_msgs/Image', { compression: 'cbor', queue_length: 1 },
    (msg) => drawImage($('thermal'), msg, hottest));
  subscribe('thermal/hottest', 'inspection_robot/GeneralTopic', { queue_length: 1 }, onHottest);
}
