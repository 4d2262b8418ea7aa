/* Files of the robot's data root over the link (file_control): directory listings and pictures as
   data: URLs, read in chunks; the newest pictures kept. */
import { control } from './link.js';

const FILE_CHUNK = 196608;   // bytes per file_control read: a multiple of 3, so the base64 chunks concatenate
const MIME = { jpg: 'image/jpeg', jpeg: 'image/jpeg', png: 'image/png' };
const PICTURE_CACHE = 60;
const pictureCache = new Map();   // path -> Promise of a data: URL, the newest PICTURE_CACHE kept

/** A picture of the robot's data root as a data: URL, read through file_control in chunks. */
export function fetchPicture(path) {
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

/** file_control list of a folder: {path, entries: [{name, type, ...}]}. */
export function listFolder(path) {
  return control('file_control', 'list', { path }, true).then(JSON.parse);
}

/** An <img> of a data: URL, once decoded. */
export function loadImage(url) {
  return new Promise((resolve, reject) => {
    const image = new Image();
    image.onload = () => resolve(image);
    image.onerror = () => reject(new Error('the picture cannot be decoded'));
    image.src = url;
  });
}
