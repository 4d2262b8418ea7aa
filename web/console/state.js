/* What more than one panel reads: the link's state and the newest robot_status. One object, written by
   the link (connected) and the status panel (status), read by the others. */

export const state = {
  connected: false,   // the websocket is open
  status: null,       // the newest robot_status message
};
