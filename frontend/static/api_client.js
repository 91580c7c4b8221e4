// ExoStudy's API client, written by backend/api/js_client.py from the server's OpenAPI
// schema and its live message models. Do not edit: after changing a route, regenerate
// it with `.venv/bin/python -m backend.api.js_client` (a test fails while it is stale).
//
// A call takes the path parameters in path order, then the body (if the operation has
// one), then an object of query parameters (if it has any):
//   api.trials.start(trialId, {})    api.results.modelEvaluation(studyId, { model_set_id })
// `.url(...)` builds the address alone (links, images), `.text(...)` reads a text answer.
import { operation, messageReader } from "./api.js";

export const accounts = Object.freeze({
  /**
   * POST /api/users: Create an account (the password policy applies).
   * @param {NewAccount} body
   * @returns {Promise<UserOut>}
   */
  addUser: operation("accounts.addUser", "POST", "/api/users", {"params": [], "query": [], "body": true}),
  /**
   * PUT /api/device-grants/{username}: Give the account the device grant (unchanged if it
   * holds one).
   * @param {string} username
   * @returns {Promise<DeviceGrantOut>}
   */
  grantDevice: operation("accounts.grantDevice", "PUT", "/api/device-grants/{username}", {"params": ["username"], "query": [], "body": false}),
  /**
   * GET /api/device-grants: Every account holding the device grant (admins hold it without
   * one).
   * @returns {Promise<Array<DeviceGrantOut>>}
   */
  listDeviceGrants: operation("accounts.listDeviceGrants", "GET", "/api/device-grants", {"params": [], "query": [], "body": false}),
  /**
   * GET /api/users: Every account, by name.
   * @returns {Promise<Array<UserOut>>}
   */
  listUsers: operation("accounts.listUsers", "GET", "/api/users", {"params": [], "query": [], "body": false}),
  /**
   * DELETE /api/device-grants/{username}: Take the device grant from the account (404 if it
   * holds none).
   * @param {string} username
   * @returns {Promise<null>}
   */
  revokeDevice: operation("accounts.revokeDevice", "DELETE", "/api/device-grants/{username}", {"params": ["username"], "query": [], "body": false}),
  /**
   * PATCH /api/users/{user_id}: Change an account's role, disable or enable it (disabling
   * ends its logins), or set a new password (its logins end).
   * @param {number} userId
   * @param {AccountUpdate} body
   * @returns {Promise<UserOut>}
   */
  updateUser: operation("accounts.updateUser", "PATCH", "/api/users/{user_id}", {"params": ["user_id"], "query": [], "body": true}),
});

export const audit = Object.freeze({
  /**
   * GET /api/audit: Who created or changed what; filter by entity and id.
   * @param {{entity?: (string|null), entity_id?: (string|null), limit?: number, offset?: number}=} query
   * @returns {Promise<Array<AuditOut>>}
   */
  list: operation("audit.list", "GET", "/api/audit", {"params": [], "query": ["entity", "entity_id", "limit", "offset"], "body": false}),
});

export const auth = Object.freeze({
  /**
   * POST /api/auth/password: Change one's own password; every other login of the account
   * ends.
   * @param {PasswordChange} body
   * @returns {Promise<null>}
   */
  changePassword: operation("auth.changePassword", "POST", "/api/auth/password", {"params": [], "query": [], "body": true}),
  /**
   * POST /api/auth/login: Log in from a browser: sets the httponly session cookie and the
   * CSRF cookie (whose value the pages send as `X-CSRF-Token` with every change).
   * @param {Credentials} body
   * @returns {Promise<LoginOut>}
   */
  login: operation("auth.login", "POST", "/api/auth/login", {"params": [], "query": [], "body": true}),
  /**
   * POST /api/auth/logout: End this login (the cookie's or the bearer token's) and the
   * WebSockets opened with it; other logins stay.
   * @returns {Promise<null>}
   */
  logout: operation("auth.logout", "POST", "/api/auth/logout", {"params": [], "query": [], "body": false}),
  /**
   * GET /api/auth/me: Who is logged in, and the warnings every page shows.
   * @returns {Promise<Me>}
   */
  me: operation("auth.me", "GET", "/api/auth/me", {"params": [], "query": [], "body": false}),
  /**
   * POST /api/auth/revoke-all: End every login of this account, this one included (a lost
   * laptop, a leaked token), and every WebSocket opened with them.
   * @returns {Promise<null>}
   */
  revokeAll: operation("auth.revokeAll", "POST", "/api/auth/revoke-all", {"params": [], "query": [], "body": false}),
  /**
   * POST /api/auth/token: Log in from a script: returns a bearer token (`Authorization:
   * Bearer ...`).
   * @param {Credentials} body
   * @returns {Promise<TokenOut>}
   */
  token: operation("auth.token", "POST", "/api/auth/token", {"params": [], "query": [], "body": true}),
});

export const cohorts = Object.freeze({
  /**
   * GET /api/cohorts/{cohort_id}/figures/{name}.{fmt}: A figure of a ready cohort: power
   * curves or metric distributions.
   * @param {number} cohortId
   * @param {("power"|"distributions")} name
   * @param {("png"|"svg")} fmt
   * @returns {Promise<*>}
   */
  cohortFigure: operation("cohorts.cohortFigure", "GET", "/api/cohorts/{cohort_id}/figures/{name}.{fmt}", {"params": ["cohort_id", "name", "fmt"], "query": [], "body": false}),
  /**
   * GET /api/cohorts/{cohort_id}/tables/{name}.{fmt}: A table of a ready cohort, as CSV or
   * Markdown.
   * @param {number} cohortId
   * @param {("participants"|"metrics"|"comparisons"|"power")} name
   * @param {("csv"|"md")} fmt
   * @returns {Promise<*>}
   */
  cohortTable: operation("cohorts.cohortTable", "GET", "/api/cohorts/{cohort_id}/tables/{name}.{fmt}", {"params": ["cohort_id", "name", "fmt"], "query": [], "body": false}),
  /**
   * GET /api/cohorts/{cohort_id}: One cohort with its analysis (`result`, the cohort.json
   * document) once ready.
   * @param {number} cohortId
   * @returns {Promise<CohortOut>}
   */
  get: operation("cohorts.get", "GET", "/api/cohorts/{cohort_id}", {"params": ["cohort_id"], "query": [], "body": false}),
  /**
   * GET /api/cohorts: Every cohort, newest first, without their results.
   * @returns {Promise<Array<CohortOut>>}
   */
  list: operation("cohorts.list", "GET", "/api/cohorts", {"params": [], "query": [], "body": false}),
  /**
   * POST /api/cohorts: Simulate a virtual cohort in the background; poll `GET
   * /api/cohorts/{id}` (or `GET /api/jobs/{job_id}`) for its progress, then its analysis.
   * Needs the experimenter role in some study (it takes minutes of the server's CPU); 409
   * while the account already has `cohort_jobs_per_account` cohorts queued or running.
   * @param {CohortIn} body
   * @returns {Promise<CohortOut>}
   */
  start: operation("cohorts.start", "POST", "/api/cohorts", {"params": [], "query": [], "body": true}),
});

export const emg = Object.freeze({
  /**
   * DELETE /api/studies/{study_id}/emg-montage: Remove the study's montage (every version);
   * 409 once a recording or a subscription uses one (a recording's channels must stay
   * mapped).
   * @param {number} studyId
   * @returns {Promise<Array<MontageOut>>}
   */
  deleteMontage: operation("emg.deleteMontage", "DELETE", "/api/studies/{study_id}/emg-montage", {"params": ["study_id"], "query": [], "body": false}),
  /**
   * GET /api/sessions/{session_id}/emg-recordings/{emg_recording_id}: One recording.
   * @param {number} sessionId
   * @param {number} emgRecordingId
   * @returns {Promise<EmgRecordingOut>}
   */
  getEmgRecording: operation("emg.getEmgRecording", "GET", "/api/sessions/{session_id}/emg-recordings/{emg_recording_id}", {"params": ["session_id", "emg_recording_id"], "query": [], "body": false}),
  /**
   * GET /api/studies/{study_id}/emg-settings: The study's EMG processing chain and
   * normalisation (defaults until set).
   * @param {number} studyId
   * @returns {Promise<EmgSettingsOut>}
   */
  getEmgSettings: operation("emg.getEmgSettings", "GET", "/api/studies/{study_id}/emg-settings", {"params": ["study_id"], "query": [], "body": false}),
  /**
   * GET /api/studies/{study_id}/emg-montage: The study's current montage (its newest
   * version); 404 before the first.
   * @param {number} studyId
   * @returns {Promise<MontageOut>}
   */
  getMontage: operation("emg.getMontage", "GET", "/api/studies/{study_id}/emg-montage", {"params": ["study_id"], "query": [], "body": false}),
  /**
   * POST /api/sessions/{session_id}/emg/edf: Import an EDF/BDF file's EMG as a recording of
   * the session: channels mapped by the study's montage (422 listing unmatched and expected
   * labels), units converted to volts (422 if not a voltage), placed on the session clock by
   * `marker` or by `trial` and `offset_s` (422 if neither or it cannot be found). Nothing is
   * stored on error.
   * @param {number} sessionId
   * @param {Body_import_edf_api_sessions__session_id__emg_edf_post} body
   * @returns {Promise<EmgRecordingOut>}
   */
  importEdf: operation("emg.importEdf", "POST", "/api/sessions/{session_id}/emg/edf", {"params": ["session_id"], "query": [], "body": true}),
  /**
   * POST /api/sessions/{session_id}/emg/xdf: Import the EMG stream of a LabRecorder XDF file
   * as a recording of the session: read by the bounded XDF reader (its `xdf_max_*` limits),
   * put on the session clock through the file's clock offsets and ExoStudy's tick stream in
   * the same file, the channels mapped by the study's montage (422 listing unmatched and
   * expected labels), units converted to volts (422 if not a voltage). NaN samples, a rate
   * that disagrees with the time stamps and gaps are stored and flagged. Nothing is stored
   * on error.
   * @param {number} sessionId
   * @param {Body_import_xdf_api_sessions__session_id__emg_xdf_post} body
   * @returns {Promise<EmgRecordingOut>}
   */
  importXdf: operation("emg.importXdf", "POST", "/api/sessions/{session_id}/emg/xdf", {"params": ["session_id"], "query": [], "body": true}),
  /**
   * GET /api/sessions/{session_id}/emg-recordings: The session's EMG recordings with their
   * span, trials and quality flags.
   * @param {number} sessionId
   * @returns {Promise<Array<EmgRecordingOut>>}
   */
  listEmgRecordings: operation("emg.listEmgRecordings", "GET", "/api/sessions/{session_id}/emg-recordings", {"params": ["session_id"], "query": [], "body": false}),
  /**
   * GET /api/sessions/{session_id}/emg-streams: The session's EMG stream subscriptions.
   * @param {number} sessionId
   * @returns {Promise<Array<EmgStreamOut>>}
   */
  listEmgStreams: operation("emg.listEmgStreams", "GET", "/api/sessions/{session_id}/emg-streams", {"params": ["session_id"], "query": [], "body": false}),
  /**
   * GET /api/studies/{study_id}/emg-montages: Every version of the study's montage, oldest
   * first.
   * @param {number} studyId
   * @returns {Promise<Array<MontageOut>>}
   */
  listMontages: operation("emg.listMontages", "GET", "/api/studies/{study_id}/emg-montages", {"params": ["study_id"], "query": [], "body": false}),
  /**
   * GET /api/sessions/{session_id}/mvc-steps: The session's MVC steps in order, with the
   * repetitions done.
   * @param {number} sessionId
   * @returns {Promise<Array<MvcStepOut>>}
   */
  listMvcSteps: operation("emg.listMvcSteps", "GET", "/api/sessions/{session_id}/mvc-steps", {"params": ["session_id"], "query": [], "body": false}),
  /**
   * POST /api/sessions/{session_id}/mvc-steps/{mvc_step_id}/events: Start or stop the step's
   * next repetition: an `mvc_start` / `mvc_stop` marker (stored, shown and sent on LSL like
   * every marker) names muscle, side and repetition. 409 for a stop without a start, a start
   * while one runs, or a step whose repetitions are all done.
   * @param {number} sessionId
   * @param {number} mvcStepId
   * @param {MvcEventIn} body
   * @returns {Promise<MvcStepOut>}
   */
  mvcEvent: operation("emg.mvcEvent", "POST", "/api/sessions/{session_id}/mvc-steps/{mvc_step_id}/events", {"params": ["session_id", "mvc_step_id"], "query": [], "body": true}),
  /**
   * PUT /api/sessions/{session_id}/mvc-steps: Plan the session's MVC steps (per muscle and
   * side, repetitions, contraction and rest times); 409 once a repetition has run (its
   * markers are data) or without a montage; 422 for a muscle/side not in the montage or
   * planned twice.
   * @param {number} sessionId
   * @param {MvcPlanIn} body
   * @returns {Promise<Array<MvcStepOut>>}
   */
  planMvc: operation("emg.planMvc", "PUT", "/api/sessions/{session_id}/mvc-steps", {"params": ["session_id"], "query": [], "body": true}),
  /**
   * PUT /api/studies/{study_id}/emg-settings: Set the study's EMG processing chain and
   * normalisation method; every parameter is stored (defaults filled in) and written into
   * results and exports.
   * @param {number} studyId
   * @param {EmgSettingsIn} body
   * @returns {Promise<EmgSettingsOut>}
   */
  putEmgSettings: operation("emg.putEmgSettings", "PUT", "/api/studies/{study_id}/emg-settings", {"params": ["study_id"], "query": [], "body": true}),
  /**
   * PUT /api/studies/{study_id}/emg-montage: A new version of the study's montage (older
   * versions stay: recordings keep the version their channels were mapped by). Unknown
   * muscles and repeated channels are a 422 naming the field.
   * @param {number} studyId
   * @param {MontageIn} body
   * @returns {Promise<MontageOut>}
   */
  putMontage: operation("emg.putMontage", "PUT", "/api/studies/{study_id}/emg-montage", {"params": ["study_id"], "query": [], "body": true}),
  /**
   * POST /api/sessions/{session_id}/emg-streams: Record this LSL EMG stream with the session
   * from now on, in chunks to the EMG folder, on this server's LSL clock (clock correction).
   * The stream must be visible (409 otherwise), of type EMG, in volts (V, mV, uV), and its
   * channel labels must match the study's montage (422 listing unmatched and expected
   * labels); nothing is stored otherwise.
   * @param {number} sessionId
   * @param {EmgStreamIn} body
   * @returns {Promise<EmgStreamOut>}
   */
  subscribe: operation("emg.subscribe", "POST", "/api/sessions/{session_id}/emg-streams", {"params": ["session_id"], "query": [], "body": true}),
  /**
   * GET /api/trials/{trial_id}/emg-envelope: The stored EMG's envelope over the trial (the
   * study's processing chain, in volts, decimated to at most `points` values), the
   * recording's flags per channel, and the trial's lifts with each lift's peak, mean and
   * integral from the full-rate envelope. 409 saying why for a trial that has not run, that
   * no EMG recording covers or whose recording is still being written; 503 with Retry-After
   * while `MAX_CONCURRENT` envelopes are being computed. Lifts the recording holds under 90
   * % of are listed with `no_emg`, not measured.
   * @param {number} trialId
   * @param {{points?: number}=} query
   * @returns {Promise<TrialEmgOut>}
   */
  trialEmgEnvelope: operation("emg.trialEmgEnvelope", "GET", "/api/trials/{trial_id}/emg-envelope", {"params": ["trial_id"], "query": ["points"], "body": false}),
  /**
   * DELETE /api/sessions/{session_id}/emg-streams/{emg_stream_id}: Stop recording the
   * stream; the recording so far is finished and kept.
   * @param {number} sessionId
   * @param {number} emgStreamId
   * @returns {Promise<EmgStreamOut>}
   */
  unsubscribe: operation("emg.unsubscribe", "DELETE", "/api/sessions/{session_id}/emg-streams/{emg_stream_id}", {"params": ["session_id", "emg_stream_id"], "query": [], "body": false}),
});

export const hardware = Object.freeze({
  /**
   * POST /api/hardware/direction: Step b: flex the `side` hip during the capture; stores its
   * encoders' signs.
   * @param {DirectionIn} body
   * @returns {Promise<StepResultOut>}
   */
  direction: operation("hardware.direction", "POST", "/api/hardware/direction", {"params": [], "query": [], "body": true}),
  /**
   * POST /api/hardware/profile: Close the bring-up: `complete` (in effect from now on, on
   * the device it was made on) if every step passed, else `failed`. 409 while something
   * runs, and when the draft expired or belongs to another device.
   * @param {FinishIn} body
   * @returns {Promise<ProfileOut>}
   */
  finish: operation("hardware.finish", "POST", "/api/hardware/profile", {"params": [], "query": [], "body": true}),
  /**
   * POST /api/hardware/release: Step f: energise one side, stop the firmware's heartbeat
   * output, time the hardware monitor's release of the drivers (device clock; at most 30 ms
   * + 2 sample periods).
   * @param {ReleaseIn} body
   * @returns {Promise<StepResultOut>}
   */
  hardwareRelease: operation("hardware.hardwareRelease", "POST", "/api/hardware/release", {"params": [], "query": [], "body": true}),
  /**
   * GET /api/hardware: The bring-up in progress, the profile in effect and the layout
   * applied now.
   * @returns {Promise<HardwareStateOut>}
   */
  hardwareState: operation("hardware.hardwareState", "GET", "/api/hardware", {"params": [], "query": [], "body": false}),
  /**
   * POST /api/hardware/link: Step g: the link's statistics (drops by reason, gaps, timing).
   * @returns {Promise<StepResultOut>}
   */
  link: operation("hardware.link", "POST", "/api/hardware/link", {"params": [], "query": [], "body": false}),
  /**
   * POST /api/hardware/offset: Step c: the cam encoders' zeros so that alpha is 0 while
   * unlocked.
   * @param {CaptureIn} body
   * @returns {Promise<StepResultOut>}
   */
  offset: operation("hardware.offset", "POST", "/api/hardware/offset", {"params": [], "query": [], "body": true}),
  /**
   * GET /api/hardware/profiles/{profile_id}: One hardware profile.
   * @param {number} profileId
   * @returns {Promise<ProfileOut>}
   */
  profile: operation("hardware.profile", "GET", "/api/hardware/profiles/{profile_id}", {"params": ["profile_id"], "query": [], "body": false}),
  /**
   * GET /api/hardware/profiles: Every hardware profile, newest first.
   * @returns {Promise<Array<ProfileOut>>}
   */
  profiles: operation("hardware.profiles", "GET", "/api/hardware/profiles", {"params": [], "query": [], "body": false}),
  /**
   * POST /api/hardware/pulse: Step d: one solenoid pulse (at most 300 ms) on an unloaded
   * device nobody wears.
   * @param {PulseIn} body
   * @returns {Promise<StepResultOut>}
   */
  pulse: operation("hardware.pulse", "POST", "/api/hardware/pulse", {"params": [], "query": [], "body": true}),
  /**
   * POST /api/hardware/watchdog: Step e: energise one side, stop commanding, time the
   * device's watchdog release.
   * @param {WatchdogIn} body
   * @returns {Promise<StepResultOut>}
   */
  watchdog: operation("hardware.watchdog", "POST", "/api/hardware/watchdog", {"params": [], "query": [], "body": true}),
  /**
   * POST /api/hardware/zero: Step a: average `seconds` of still standing; each encoder's
   * count becomes its zero.
   * @param {CaptureIn} body
   * @returns {Promise<StepResultOut>}
   */
  zero: operation("hardware.zero", "POST", "/api/hardware/zero", {"params": [], "query": [], "body": true}),
});

export const health = Object.freeze({
  /**
   * GET /api/health: Is the worker alive, is the device sending, are ticks being stored?
   * @returns {Promise<Health>}
   */
  health: operation("health.health", "GET", "/api/health", {"params": [], "query": [], "body": false}),
});

export const lab = Object.freeze({
  /**
   * POST /api/sessions/{session_id}/markers: An event marker now: stamped with the newest
   * tick, stored with the session's running trial (if that tick is the trial's), drawn on
   * the consoles and sent on the LSL marker stream. 409 while a trial runs whose ticks have
   * ended (a timed trial past its duration: stop it first).
   * @param {number} sessionId
   * @param {MarkerIn} body
   * @returns {Promise<MarkerOut>}
   */
  addMarker: operation("lab.addMarker", "POST", "/api/sessions/{session_id}/markers", {"params": ["session_id"], "query": [], "body": true}),
  /**
   * POST /api/sessions/{session_id}/xdf: Attach a LabRecorder XDF file (at most
   * `max_upload_bytes`): kept whole, its streams aligned with the session's ticks on the LSL
   * clock, and for each the trials it covers. ExoStudy's own reader decodes it in a child
   * process within the `xdf_max_*` settings and `xdf_parse_seconds`; a malformed file, one
   * that declares more than it holds or more than those limits, or an ExoStudy tick stream
   * with unusable fields is refused (422, saying what and where).
   * @param {number} sessionId
   * @param {Body_attach_xdf_api_sessions__session_id__xdf_post} body
   * @returns {Promise<XdfAttachmentOut>}
   */
  attachXdf: operation("lab.attachXdf", "POST", "/api/sessions/{session_id}/xdf", {"params": ["session_id"], "query": [], "body": true}),
  /**
   * GET /api/sessions/{session_id}/xdf/{attachment_id}/file: The attached file, byte for
   * byte.
   * @param {number} sessionId
   * @param {number} attachmentId
   * @returns {Promise<*>}
   */
  downloadXdf: operation("lab.downloadXdf", "GET", "/api/sessions/{session_id}/xdf/{attachment_id}/file", {"params": ["session_id", "attachment_id"], "query": [], "body": false}),
  /**
   * GET /api/studies/{study_id}/export.bids.zip: The study as a BIDS-motion dataset:
   * participants, one motion file per trial with channels and events (lifts, locks,
   * markers), questionnaires as phenotype files, attached XDF files as source data. De-
   * identified fields only. Controllers are named for the study's owner only; anyone else
   * gets blinded labels (`acq-A`). 409 if no trial of the study has ticks yet (a BIDS motion
   * dataset needs one).
   * @param {number} studyId
   * @returns {Promise<*>}
   */
  exportBids: operation("lab.exportBids", "GET", "/api/studies/{study_id}/export.bids.zip", {"params": ["study_id"], "query": [], "body": false}),
  /**
   * GET /api/studies/{study_id}/marker-labels: The study's marker buttons, in hotkey order
   * (1-9).
   * @param {number} studyId
   * @returns {Promise<MarkerLabels>}
   */
  getMarkerLabels: operation("lab.getMarkerLabels", "GET", "/api/studies/{study_id}/marker-labels", {"params": ["study_id"], "query": [], "body": false}),
  /**
   * GET /api/sessions/{session_id}/marker-streams: The session's subscriptions to other
   * software's marker streams.
   * @param {number} sessionId
   * @returns {Promise<Array<MarkerStreamOut>>}
   */
  listMarkerStreams: operation("lab.listMarkerStreams", "GET", "/api/sessions/{session_id}/marker-streams", {"params": ["session_id"], "query": [], "body": false}),
  /**
   * GET /api/sessions/{session_id}/xdf: The session's XDF files with their aligned streams.
   * @param {number} sessionId
   * @returns {Promise<Array<XdfAttachmentOut>>}
   */
  listXdf: operation("lab.listXdf", "GET", "/api/sessions/{session_id}/xdf", {"params": ["session_id"], "query": [], "body": false}),
  /**
   * PUT /api/studies/{study_id}/marker-labels: Replace the study's marker buttons.
   * @param {number} studyId
   * @param {MarkerLabels} body
   * @returns {Promise<MarkerLabels>}
   */
  putMarkerLabels: operation("lab.putMarkerLabels", "PUT", "/api/studies/{study_id}/marker-labels", {"params": ["study_id"], "query": [], "body": true}),
  /**
   * GET /api/sessions/{session_id}/marker-labels: The marker buttons of the study the
   * session belongs to.
   * @param {number} sessionId
   * @returns {Promise<MarkerLabels>}
   */
  sessionMarkerLabels: operation("lab.sessionMarkerLabels", "GET", "/api/sessions/{session_id}/marker-labels", {"params": ["session_id"], "query": [], "body": false}),
  /**
   * GET /api/sessions/{session_id}/markers: The session's markers in the order they were
   * stored.
   * @param {number} sessionId
   * @returns {Promise<Array<MarkerOut>>}
   */
  sessionMarkers: operation("lab.sessionMarkers", "GET", "/api/sessions/{session_id}/markers", {"params": ["session_id"], "query": [], "body": false}),
  /**
   * POST /api/sessions/{session_id}/marker-streams: Store this marker stream's markers with
   * the session (and its running trial) from now on. One session at a time listens to a
   * given stream.
   * @param {number} sessionId
   * @param {MarkerStreamIn} body
   * @returns {Promise<MarkerStreamOut>}
   */
  subscribe: operation("lab.subscribe", "POST", "/api/sessions/{session_id}/marker-streams", {"params": ["session_id"], "query": [], "body": true}),
  /**
   * GET /api/trials/{trial_id}/markers: A trial's markers in tick-time order (`t` is on the
   * trial's tick time axis).
   * @param {number} trialId
   * @returns {Promise<Array<MarkerOut>>}
   */
  trialMarkers: operation("lab.trialMarkers", "GET", "/api/trials/{trial_id}/markers", {"params": ["trial_id"], "query": [], "body": false}),
  /**
   * DELETE /api/sessions/{session_id}/marker-streams/{subscription_id}: Stop storing the
   * stream's markers (those stored stay).
   * @param {number} sessionId
   * @param {number} subscriptionId
   * @returns {Promise<MarkerStreamOut>}
   */
  unsubscribe: operation("lab.unsubscribe", "DELETE", "/api/sessions/{session_id}/marker-streams/{subscription_id}", {"params": ["session_id", "subscription_id"], "query": [], "body": false}),
  /**
   * GET /api/sessions/{session_id}/lsl-streams: The LSL streams visible on the network now
   * (marker streams first).
   * @param {number} sessionId
   * @returns {Promise<Array<LslStreamOut>>}
   */
  visibleStreams: operation("lab.visibleStreams", "GET", "/api/sessions/{session_id}/lsl-streams", {"params": ["session_id"], "query": [], "body": false}),
});

export const models = Object.freeze({
  /**
   * POST /api/studies/{study_id}/utility-sets: Compute utilities from the built-in simulated
   * reference human dataset.
   * @param {number} studyId
   * @param {UtilitySetIn} body
   * @returns {Promise<UtilitySetOut>}
   */
  computeUtilitySet: operation("models.computeUtilitySet", "POST", "/api/studies/{study_id}/utility-sets", {"params": ["study_id"], "query": [], "body": true}),
  /**
   * POST /api/studies/{study_id}/model-sets: Fit PPCA motion models from labelled segments
   * of this study's recordings. Returns at once with the job id; poll `GET
   * /api/jobs/{job_id}`.
   * @param {number} studyId
   * @param {ModelSetIn} body
   * @returns {Promise<ModelSetOut>}
   */
  fit: operation("models.fit", "POST", "/api/studies/{study_id}/model-sets", {"params": ["study_id"], "query": [], "body": true}),
  /**
   * GET /api/jobs/{job_id}: A background job's status, progress (0..1) and message: a model
   * fit or utility table (the viewer role in its study) or a virtual cohort (which belongs
   * to no study: the viewer role in some study). `done`, `failed` and `cancelled` are final.
   * @param {number} jobId
   * @returns {Promise<JobOut>}
   */
  getJob: operation("models.getJob", "GET", "/api/jobs/{job_id}", {"params": ["job_id"], "query": [], "body": false}),
  /**
   * GET /api/model-sets/{model_set_id}: One model set's record.
   * @param {number} modelSetId
   * @returns {Promise<ModelSetOut>}
   */
  getModelSet: operation("models.getModelSet", "GET", "/api/model-sets/{model_set_id}", {"params": ["model_set_id"], "query": [], "body": false}),
  /**
   * GET /api/utility-sets/{utility_set_id}: One utility set's record.
   * @param {number} utilitySetId
   * @returns {Promise<UtilitySetOut>}
   */
  getUtilitySet: operation("models.getUtilitySet", "GET", "/api/utility-sets/{utility_set_id}", {"params": ["utility_set_id"], "query": [], "body": false}),
  /**
   * POST /api/studies/{study_id}/utility-sets/import: Compute utilities from a lab's own
   * human motion data (CSV upload).
   * @param {number} studyId
   * @param {Body_import_utility_set_api_studies__study_id__utility_sets_import_post} body
   * @returns {Promise<UtilitySetOut>}
   */
  importUtilitySet: operation("models.importUtilitySet", "POST", "/api/studies/{study_id}/utility-sets/import", {"params": ["study_id"], "query": [], "body": true}),
  /**
   * GET /api/studies/{study_id}/model-sets: The study's model sets, newest last.
   * @param {number} studyId
   * @returns {Promise<Array<ModelSetOut>>}
   */
  listModelSets: operation("models.listModelSets", "GET", "/api/studies/{study_id}/model-sets", {"params": ["study_id"], "query": [], "body": false}),
  /**
   * GET /api/studies/{study_id}/utility-sets: The study's utility sets.
   * @param {number} studyId
   * @returns {Promise<Array<UtilitySetOut>>}
   */
  listUtilitySets: operation("models.listUtilitySets", "GET", "/api/studies/{study_id}/utility-sets", {"params": ["study_id"], "query": [], "body": false}),
  /**
   * GET /api/model-sets/{model_set_id}/document: The fitted model set as versioned JSON (the
   * format `exostudy replay` reads).
   * @param {number} modelSetId
   * @returns {Promise<ModelSetDocument>}
   */
  modelSetDocument: operation("models.modelSetDocument", "GET", "/api/model-sets/{model_set_id}/document", {"params": ["model_set_id"], "query": [], "body": false}),
  /**
   * GET /api/utility-sets/{utility_set_id}/curves: Each action's utility minus "no lock",
   * per motion, over progress.
   * @param {number} utilitySetId
   * @returns {Promise<UtilityCurves>}
   */
  utilityCurves: operation("models.utilityCurves", "GET", "/api/utility-sets/{utility_set_id}/curves", {"params": ["utility_set_id"], "query": [], "body": false}),
  /**
   * GET /api/utility-sets/{utility_set_id}/document: The utility set as versioned JSON (the
   * format `exostudy replay` reads).
   * @param {number} utilitySetId
   * @returns {Promise<UtilitySetDocument>}
   */
  utilitySetDocument: operation("models.utilitySetDocument", "GET", "/api/utility-sets/{utility_set_id}/document", {"params": ["utility_set_id"], "query": [], "body": false}),
});

export const participantForms = Object.freeze({
  /**
   * GET /api/participant-forms/{token}: The forms due on this link, with blinded condition
   * labels only.
   * @param {string} token
   * @returns {Promise<ParticipantFormsOut>}
   */
  get: operation("participantForms.get", "GET", "/api/participant-forms/{token}", {"params": ["token"], "query": [], "body": false}),
  /**
   * POST /api/participant-forms/{token}/responses: Answer one form. The answers are
   * validated against the instrument (every bad item is named), scored, and stored with the
   * instrument version; 409 if this form was already answered.
   * @param {string} token
   * @param {AnswersIn} body
   * @returns {Promise<SubmissionOut>}
   */
  submitAnswers: operation("participantForms.submitAnswers", "POST", "/api/participant-forms/{token}/responses", {"params": ["token"], "query": [], "body": true}),
  /**
   * POST /api/participant-forms/{token}/preference: Say which condition was preferred: a
   * label as shown, or "none".
   * @param {string} token
   * @param {PreferenceIn} body
   * @returns {Promise<SubmissionOut>}
   */
  submitPreference: operation("participantForms.submitPreference", "POST", "/api/participant-forms/{token}/preference", {"params": ["token"], "query": [], "body": true}),
});

export const participants = Object.freeze({
  /**
   * POST /api/participants/{participant_id}/conditions: Blind a controller behind a label;
   * 409 if the label or controller already has an entry for this participant (a key never
   * changes once forms may use it).
   * @param {number} participantId
   * @param {ConditionIn} body
   * @returns {Promise<ConditionOut>}
   */
  addCondition: operation("participants.addCondition", "POST", "/api/participants/{participant_id}/conditions", {"params": ["participant_id"], "query": [], "body": true}),
  /**
   * POST /api/studies/{study_id}/participants: Enrol a participant under a pseudonymous
   * code; 409 if the code exists in the study. A site-limited member enrols into their own
   * site only.
   * @param {number} studyId
   * @param {ParticipantIn} body
   * @returns {Promise<ParticipantOut>}
   */
  create: operation("participants.create", "POST", "/api/studies/{study_id}/participants", {"params": ["study_id"], "query": [], "body": true}),
  /**
   * GET /api/participants/{participant_id}: One participant.
   * @param {number} participantId
   * @returns {Promise<ParticipantOut>}
   */
  get: operation("participants.get", "GET", "/api/participants/{participant_id}", {"params": ["participant_id"], "query": [], "body": false}),
  /**
   * GET /api/studies/{study_id}/participants: The participants of a study, by code (a site-
   * limited member: that site's).
   * @param {number} studyId
   * @returns {Promise<Array<ParticipantOut>>}
   */
  list: operation("participants.list", "GET", "/api/studies/{study_id}/participants", {"params": ["study_id"], "query": [], "body": false}),
  /**
   * GET /api/participants/{participant_id}/conditions: The participant's blinded labels; the
   * blinding key (which controller each label stands for) only for the study's owners,
   * `null` for everyone else.
   * @param {number} participantId
   * @returns {Promise<Array<ConditionOut>>}
   */
  listConditions: operation("participants.listConditions", "GET", "/api/participants/{participant_id}/conditions", {"params": ["participant_id"], "query": [], "body": false}),
  /**
   * PATCH /api/participants/{participant_id}: Correct a participant's record; `null` clears
   * an optional field.
   * @param {number} participantId
   * @param {ParticipantUpdate} body
   * @returns {Promise<ParticipantOut>}
   */
  update: operation("participants.update", "PATCH", "/api/participants/{participant_id}", {"params": ["participant_id"], "query": [], "body": true}),
  /**
   * POST /api/participants/{participant_id}/withdraw: A participant withdraws: their data is
   * erased, or (when the study's protocol says "exclude") kept, marked withdrawn and left
   * out of results and exports. The audit entry names the participant id only, never the
   * erased data.
   * @param {number} participantId
   * @returns {Promise<WithdrawalOut>}
   */
  withdraw: operation("participants.withdraw", "POST", "/api/participants/{participant_id}/withdraw", {"params": ["participant_id"], "query": [], "body": false}),
});

export const personalisation = Object.freeze({
  /**
   * POST /api/participants/{participant_id}/personal-model-sets: Fit the participant's
   * personal model set from their labelled demonstrations (the population set adapted to
   * them, or fitted from them alone). Returns at once with the job id; poll `GET
   * /api/jobs/{job_id}`; the set is a model set (`/api/model-sets/{id}`, `/document`) of
   * kind `personal`.
   * @param {number} participantId
   * @param {PersonalModelSetIn} body
   * @returns {Promise<PersonalModelSetOut>}
   */
  fitPersonalModelSet: operation("personalisation.fitPersonalModelSet", "POST", "/api/participants/{participant_id}/personal-model-sets", {"params": ["participant_id"], "query": [], "body": true}),
  /**
   * GET /api/prior-sets/{prior_set_id}: One prior set.
   * @param {number} priorSetId
   * @returns {Promise<PriorSetOut>}
   */
  getPriorSet: operation("personalisation.getPriorSet", "GET", "/api/prior-sets/{prior_set_id}", {"params": ["prior_set_id"], "query": [], "body": false}),
  /**
   * POST /api/participants/{participant_id}/prior-sets: A new version of the participant's
   * priors: learned from confirmed motions (`dirichlet`) or unconfirmed use (`label-shift-
   * em`) and projected onto the safety bound of the utility set; the equal priors; or
   * imported `values`, refused (422) outside that bound.
   * @param {number} participantId
   * @param {PriorSetIn} body
   * @returns {Promise<PriorSetOut>}
   */
  learnPriorSet: operation("personalisation.learnPriorSet", "POST", "/api/participants/{participant_id}/prior-sets", {"params": ["participant_id"], "query": [], "body": true}),
  /**
   * GET /api/participants/{participant_id}/personal-model-sets: The participant's personal
   * model sets, oldest first.
   * @param {number} participantId
   * @returns {Promise<Array<PersonalModelSetOut>>}
   */
  listPersonalModelSets: operation("personalisation.listPersonalModelSets", "GET", "/api/participants/{participant_id}/personal-model-sets", {"params": ["participant_id"], "query": [], "body": false}),
  /**
   * GET /api/participants/{participant_id}/prior-sets: The participant's prior sets, by
   * version.
   * @param {number} participantId
   * @returns {Promise<Array<PriorSetOut>>}
   */
  listPriorSets: operation("personalisation.listPriorSets", "GET", "/api/participants/{participant_id}/prior-sets", {"params": ["participant_id"], "query": [], "body": false}),
  /**
   * GET /api/studies/{study_id}/personal-model-sets: Every personal model set of the study's
   * participants, oldest first.
   * @param {number} studyId
   * @returns {Promise<Array<PersonalModelSetOut>>}
   */
  listStudyPersonalModelSets: operation("personalisation.listStudyPersonalModelSets", "GET", "/api/studies/{study_id}/personal-model-sets", {"params": ["study_id"], "query": [], "body": false}),
  /**
   * GET /api/studies/{study_id}/prior-sets: Every prior set of the study's participants,
   * oldest first.
   * @param {number} studyId
   * @returns {Promise<Array<PriorSetOut>>}
   */
  listStudyPriorSets: operation("personalisation.listStudyPriorSets", "GET", "/api/studies/{study_id}/prior-sets", {"params": ["study_id"], "query": [], "body": false}),
});

export const preferences = Object.freeze({
  /**
   * GET /api/participants/{participant_id}/preferences: The participant's preferences with
   * the controller each label stands for (for the study's owners; null for other roles).
   * @param {number} participantId
   * @returns {Promise<Array<PreferenceOut>>}
   */
  list: operation("preferences.list", "GET", "/api/participants/{participant_id}/preferences", {"params": ["participant_id"], "query": [], "body": false}),
});

export const questionnaires = Object.freeze({
  /**
   * POST /api/participants/{participant_id}/links: A single-use link for the participant to
   * fill in the forms due (and, if asked, say which condition they preferred). Each form is
   * pinned to one instrument row of the participant's study (or a built-in). The token is in
   * this answer only.
   * @param {number} participantId
   * @param {LinkIn} body
   * @returns {Promise<LinkCreated>}
   */
  createLink: operation("questionnaires.createLink", "POST", "/api/participants/{participant_id}/links", {"params": ["participant_id"], "query": [], "body": true}),
  /**
   * GET /api/instruments/{key}/{version}: One built-in instrument version with its full
   * definition.
   * @param {string} key
   * @param {string} version
   * @returns {Promise<InstrumentOut>}
   */
  getInstrument: operation("questionnaires.getInstrument", "GET", "/api/instruments/{key}/{version}", {"params": ["key", "version"], "query": [], "body": false}),
  /**
   * GET /api/studies/{study_id}/instruments/{key}/{version}: One instrument version the
   * study may use, with its full definition.
   * @param {number} studyId
   * @param {string} key
   * @param {string} version
   * @returns {Promise<InstrumentOut>}
   */
  getStudyInstrument: operation("questionnaires.getStudyInstrument", "GET", "/api/studies/{study_id}/instruments/{key}/{version}", {"params": ["study_id", "key", "version"], "query": [], "body": false}),
  /**
   * POST /api/studies/{study_id}/instruments: Import the study's own definition file (the
   * JSON body); only this study's links can use it. It is validated like the built-ins, and
   * its form must stay usable: at most 101 scale points, one label per point with its own
   * words, at most 5,000 answer choices (items x points); the key of a built-in instrument
   * is refused (422), and 409 if the study has this key and version (add a new version).
   * @param {number} studyId
   * @param {ImportedInstrument} body
   * @returns {Promise<InstrumentOut>}
   */
  importInstrument: operation("questionnaires.importInstrument", "POST", "/api/studies/{study_id}/instruments", {"params": ["study_id"], "query": [], "body": true}),
  /**
   * GET /api/instruments: The built-in instruments (a study's own ones:
   * `/api/studies/{id}/instruments`); `wording` tells whose item texts they are.
   * @returns {Promise<Array<InstrumentSummary>>}
   */
  listInstruments: operation("questionnaires.listInstruments", "GET", "/api/instruments", {"params": [], "query": [], "body": false}),
  /**
   * GET /api/participants/{participant_id}/links: The participant's links (without tokens)
   * and whether they were used.
   * @param {number} participantId
   * @returns {Promise<Array<LinkOut>>}
   */
  listLinks: operation("questionnaires.listLinks", "GET", "/api/participants/{participant_id}/links", {"params": ["participant_id"], "query": [], "body": false}),
  /**
   * GET /api/participants/{participant_id}/instruments: The instruments a link for this
   * participant may ask for (the console's list).
   * @param {number} participantId
   * @returns {Promise<Array<InstrumentSummary>>}
   */
  listParticipantInstruments: operation("questionnaires.listParticipantInstruments", "GET", "/api/participants/{participant_id}/instruments", {"params": ["participant_id"], "query": [], "body": false}),
  /**
   * GET /api/participants/{participant_id}/responses: The participant's scored responses,
   * unblinded (`controller`) for the study's owners; `controller` is null for other roles.
   * @param {number} participantId
   * @returns {Promise<Array<ResponseOut>>}
   */
  listResponses: operation("questionnaires.listResponses", "GET", "/api/participants/{participant_id}/responses", {"params": ["participant_id"], "query": [], "body": false}),
  /**
   * GET /api/studies/{study_id}/instruments: The instruments the study's links may use: the
   * built-ins and the study's own.
   * @param {number} studyId
   * @returns {Promise<Array<InstrumentSummary>>}
   */
  listStudyInstruments: operation("questionnaires.listStudyInstruments", "GET", "/api/studies/{study_id}/instruments", {"params": ["study_id"], "query": [], "body": false}),
});

export const recordings = Object.freeze({
  /**
   * POST /api/recordings/{recording_id}/segments: Add a segment by hand.
   * @param {number} recordingId
   * @param {SegmentIn} body
   * @returns {Promise<SegmentOut>}
   */
  addSegment: operation("recordings.addSegment", "POST", "/api/recordings/{recording_id}/segments", {"params": ["recording_id"], "query": [], "body": true}),
  /**
   * POST /api/recordings/{recording_id}/segment: Find the lifts automatically. Segments the
   * experimenter edited are kept unless `replace=true`. In simulation the ground truth
   * suggests each segment's label.
   * @param {number} recordingId
   * @param {{replace?: boolean}=} query
   * @returns {Promise<Array<SegmentOut>>}
   */
  autoSegment: operation("recordings.autoSegment", "POST", "/api/recordings/{recording_id}/segment", {"params": ["recording_id"], "query": ["replace"], "body": false}),
  /**
   * DELETE /api/segments/{segment_id}: Remove a segment that is not a lift.
   * @param {number} segmentId
   * @returns {Promise<null>}
   */
  deleteSegment: operation("recordings.deleteSegment", "DELETE", "/api/segments/{segment_id}", {"params": ["segment_id"], "query": [], "body": false}),
  /**
   * PATCH /api/segments/{segment_id}: Drag an edge or change the label.
   * @param {number} segmentId
   * @param {SegmentUpdate} body
   * @returns {Promise<SegmentOut>}
   */
  editSegment: operation("recordings.editSegment", "PATCH", "/api/segments/{segment_id}", {"params": ["segment_id"], "query": [], "body": true}),
  /**
   * GET /api/recordings/{recording_id}: One recording.
   * @param {number} recordingId
   * @returns {Promise<RecordingOut>}
   */
  get: operation("recordings.get", "GET", "/api/recordings/{recording_id}", {"params": ["recording_id"], "query": [], "body": false}),
  /**
   * GET /api/sessions/{session_id}/recordings: A session's recordings, oldest first.
   * @param {number} sessionId
   * @returns {Promise<Array<RecordingOut>>}
   */
  list: operation("recordings.list", "GET", "/api/sessions/{session_id}/recordings", {"params": ["session_id"], "query": [], "body": false}),
  /**
   * GET /api/recordings/{recording_id}/segments: A recording's lift segments in time order.
   * @param {number} recordingId
   * @returns {Promise<Array<SegmentOut>>}
   */
  listSegments: operation("recordings.listSegments", "GET", "/api/recordings/{recording_id}/segments", {"params": ["recording_id"], "query": [], "body": false}),
  /**
   * GET /api/recordings/{recording_id}/angles: Hip angles (rad) and device time (s) of a
   * stopped recording.
   * @param {number} recordingId
   * @returns {Promise<RecordingAngles>}
   */
  recordingAngles: operation("recordings.recordingAngles", "GET", "/api/recordings/{recording_id}/angles", {"params": ["recording_id"], "query": [], "body": false}),
  /**
   * POST /api/sessions/{session_id}/recordings: Put the worker in recording mode (no locks)
   * and start a recording. 409 while a trial or another recording runs (under the runtime's
   * activity lock; the database's unique index refuses a second running recording in any
   * case).
   * @param {number} sessionId
   * @param {RecordingIn} body
   * @returns {Promise<RecordingOut>}
   */
  start: operation("recordings.start", "POST", "/api/sessions/{session_id}/recordings", {"params": ["session_id"], "query": [], "body": true}),
  /**
   * POST /api/recordings/{recording_id}/stop: End the recording: the worker starts a new
   * idle run and the ticks are stored.
   * @param {number} recordingId
   * @returns {Promise<RecordingOut>}
   */
  stop: operation("recordings.stop", "POST", "/api/recordings/{recording_id}/stop", {"params": ["recording_id"], "query": [], "body": false}),
});

export const replication = Object.freeze({
  /**
   * GET /api/replication/figures/{name}.{fmt}: One figure of the newest report.
   * @param {string} name
   * @param {("png"|"svg")} fmt
   * @returns {Promise<*>}
   */
  figure: operation("replication.figure", "GET", "/api/replication/figures/{name}.{fmt}", {"params": ["name", "fmt"], "query": [], "body": false}),
  /**
   * GET /api/replication: The newest replication job (status, progress, message) and the
   * newest finished report's claims; either is null when there is none.
   * @returns {Promise<ReplicationStateOut>}
   */
  latest: operation("replication.latest", "GET", "/api/replication", {"params": [], "query": [], "body": false}),
  /**
   * GET /api/replication/report: The newest report as its self-contained HTML page.
   * @returns {Promise<*>}
   */
  reportPage: operation("replication.reportPage", "GET", "/api/replication/report", {"params": [], "query": [], "body": false}),
  /**
   * POST /api/replication: Run the replication report in the background (the `cohort`
   * engine); poll `GET /api/replication` for its progress, then its claims. 409 while the
   * account already has `replication_jobs_per_account` reports queued or running.
   * @param {ReplicationIn} body
   * @returns {Promise<ReplicationStarted>}
   */
  start: operation("replication.start", "POST", "/api/replication", {"params": [], "query": [], "body": true}),
});

export const results = Object.freeze({
  /**
   * GET /api/studies/{study_id}/model-evaluation: Leave-one-participant-out: models fitted
   * without each data-collection participant, that participant's segments replayed through
   * the UMC; recognition and decision accuracy and confusion matrices.
   * @param {number} studyId
   * @param {{model_set_id?: number, utility_set_id?: (number|null), rate_hz?: (number|null)}=} query
   * @returns {Promise<ModelEvaluationOut>}
   */
  modelEvaluation: operation("results.modelEvaluation", "GET", "/api/studies/{study_id}/model-evaluation", {"params": ["study_id"], "query": ["model_set_id", "utility_set_id", "rate_hz"], "body": false}),
  /**
   * GET /api/studies/{study_id}/results: The paper's tables for the study's completed
   * trials: intent estimation and decision performance (UMC/E-UMC), false positives in
   * walking and stair walking, questionnaires (unblinded through the condition labels),
   * onset to lock; with the ground truth each trial was scored against.
   * @param {number} studyId
   * @returns {Promise<StudyResultsOut>}
   */
  study: operation("results.study", "GET", "/api/studies/{study_id}/results", {"params": ["study_id"], "query": [], "body": false}),
  /**
   * GET /api/studies/{study_id}/figures/{name}.{fmt}: Peak exoskeleton torques per lift, or
   * the onset-to-lock histogram.
   * @param {number} studyId
   * @param {("peak_torques"|"onset_to_lock")} name
   * @param {("png"|"svg")} fmt
   * @returns {Promise<*>}
   */
  studyFigure: operation("results.studyFigure", "GET", "/api/studies/{study_id}/figures/{name}.{fmt}", {"params": ["study_id", "name", "fmt"], "query": [], "body": false}),
  /**
   * GET /api/studies/{study_id}/muscle-results: Muscle activity from the stored EMG: per
   * lift (CSV `lifts`), per controller the mean over participants with its 95 % interval,
   * the reduction against each baseline and the repeated-measures test, with every
   * processing parameter (`method`) and each trial's quality flags.
   * @param {number} studyId
   * @returns {Promise<MuscleResultsOut>}
   */
  studyMuscle: operation("results.studyMuscle", "GET", "/api/studies/{study_id}/muscle-results", {"params": ["study_id"], "query": [], "body": false}),
  /**
   * GET /api/studies/{study_id}/muscle-figures/{name}.{fmt}: The envelope over the
   * normalised lift cycle per controller, or the reduction per muscle and controller against
   * no exoskeleton (else the first baseline).
   * @param {number} studyId
   * @param {("muscle_envelopes"|"muscle_reduction")} name
   * @param {("png"|"svg")} fmt
   * @returns {Promise<*>}
   */
  studyMuscleFigure: operation("results.studyMuscleFigure", "GET", "/api/studies/{study_id}/muscle-figures/{name}.{fmt}", {"params": ["study_id", "name", "fmt"], "query": [], "body": false}),
  /**
   * GET /api/studies/{study_id}/muscle-results/{table}.{fmt}: A muscle-activity table as CSV
   * (the method in `#` lines first); Markdown gives the reductions against each baseline
   * whatever the table.
   * @param {number} studyId
   * @param {("lifts"|"summary"|"reductions"|"repeated_measures")} table
   * @param {("csv"|"md")} fmt
   * @returns {Promise<*>}
   */
  studyMuscleTable: operation("results.studyMuscleTable", "GET", "/api/studies/{study_id}/muscle-results/{table}.{fmt}", {"params": ["study_id", "table", "fmt"], "query": [], "body": false}),
  /**
   * GET /api/studies/{study_id}/results/{table}.{fmt}: One table: CSV in long form (every
   * count), Markdown in the paper's layout.
   * @param {number} studyId
   * @param {("performance"|"performance_by_kind"|"false_positives"|"questionnaires"|"onset_to_lock"|"lifts")} table
   * @param {("csv"|"md")} fmt
   * @returns {Promise<*>}
   */
  studyTable: operation("results.studyTable", "GET", "/api/studies/{study_id}/results/{table}.{fmt}", {"params": ["study_id", "table", "fmt"], "query": [], "body": false}),
  /**
   * GET /api/trials/{trial_id}/figures/timeline.{fmt}: The trial's controller output in five
   * panels (hip angles against the trial's motion models, actions, posteriors, progress,
   * lock commands).
   * @param {number} trialId
   * @param {("png"|"svg")} fmt
   * @returns {Promise<*>}
   */
  trialTimeline: operation("results.trialTimeline", "GET", "/api/trials/{trial_id}/figures/timeline.{fmt}", {"params": ["trial_id", "fmt"], "query": [], "body": false}),
  /**
   * POST /api/trials/{trial_id}/what-if: Replay the trial's stored raw hip angles through
   * another controller or settings (the live tick code) and return the original's and the
   * replay's metrics side by side. The stored trial and its ticks are not changed.
   * @param {number} trialId
   * @param {WhatIfIn} body
   * @returns {Promise<WhatIfOut>}
   */
  trialWhatIf: operation("results.trialWhatIf", "POST", "/api/trials/{trial_id}/what-if", {"params": ["trial_id"], "query": [], "body": true}),
});

export const sessions = Object.freeze({
  /**
   * POST /api/participants/{participant_id}/sessions: Start a session record with the
   * exoskeleton's settings.
   * @param {number} participantId
   * @param {SessionIn} body
   * @returns {Promise<SessionOut>}
   */
  create: operation("sessions.create", "POST", "/api/participants/{participant_id}/sessions", {"params": ["participant_id"], "query": [], "body": true}),
  /**
   * GET /api/sessions/{session_id}: One session.
   * @param {number} sessionId
   * @returns {Promise<SessionOut>}
   */
  get: operation("sessions.get", "GET", "/api/sessions/{session_id}", {"params": ["session_id"], "query": [], "body": false}),
  /**
   * GET /api/participants/{participant_id}/sessions: A participant's sessions in the order
   * they happened.
   * @param {number} participantId
   * @returns {Promise<Array<SessionOut>>}
   */
  list: operation("sessions.list", "GET", "/api/participants/{participant_id}/sessions", {"params": ["participant_id"], "query": [], "body": false}),
  /**
   * PATCH /api/sessions/{session_id}: Correct the precompression or the notes.
   * @param {number} sessionId
   * @param {SessionUpdate} body
   * @returns {Promise<SessionOut>}
   */
  update: operation("sessions.update", "PATCH", "/api/sessions/{session_id}", {"params": ["session_id"], "query": [], "body": true}),
});

export const studies = Object.freeze({
  /**
   * POST /api/studies/{study_id}/consent: Add a consent document version (versions are never
   * edited).
   * @param {number} studyId
   * @param {ConsentIn} body
   * @returns {Promise<ConsentOut>}
   */
  addConsent: operation("studies.addConsent", "POST", "/api/studies/{study_id}/consent", {"params": ["study_id"], "query": [], "body": true}),
  /**
   * POST /api/studies: Create a study; its creator is its owner. 409 if the name is taken.
   * @param {StudyIn} body
   * @returns {Promise<StudyOut>}
   */
  create: operation("studies.create", "POST", "/api/studies", {"params": [], "query": [], "body": true}),
  /**
   * GET /api/studies/{study_id}/export-deidentified.zip: The study's export for sharing:
   * participants re-coded, free text and account ids removed, ages above 89 as 90, dates
   * shifted per participant; `data_dictionary.csv` says what was done to each column. The
   * blinding key (`condition_labels.csv` `controller`) is filled in for the study's owner
   * only. The full export needs the owner role.
   * @param {number} studyId
   * @returns {Promise<*>}
   */
  exportDeidentified: operation("studies.exportDeidentified", "GET", "/api/studies/{study_id}/export-deidentified.zip", {"params": ["study_id"], "query": [], "body": false}),
  /**
   * GET /api/studies/{study_id}: One study.
   * @param {number} studyId
   * @returns {Promise<StudyOut>}
   */
  get: operation("studies.get", "GET", "/api/studies/{study_id}", {"params": ["study_id"], "query": [], "body": false}),
  /**
   * GET /api/studies: The studies the caller is a member of (an admin: every study), oldest
   * first.
   * @returns {Promise<Array<StudyOut>>}
   */
  list: operation("studies.list", "GET", "/api/studies", {"params": [], "query": [], "body": false}),
  /**
   * GET /api/studies/{study_id}/consent: The study's consent document versions, oldest
   * first.
   * @param {number} studyId
   * @returns {Promise<Array<ConsentOut>>}
   */
  listConsent: operation("studies.listConsent", "GET", "/api/studies/{study_id}/consent", {"params": ["study_id"], "query": [], "body": false}),
  /**
   * GET /api/studies/{study_id}/members: Who has which role in the study (and which site, if
   * limited).
   * @param {number} studyId
   * @returns {Promise<Array<MemberOut>>}
   */
  listMembers: operation("studies.listMembers", "GET", "/api/studies/{study_id}/members", {"params": ["study_id"], "query": [], "body": false}),
  /**
   * DELETE /api/studies/{study_id}/members/{username}: Take an account's role in the study
   * away (its creator stays owner).
   * @param {number} studyId
   * @param {string} username
   * @returns {Promise<null>}
   */
  removeMember: operation("studies.removeMember", "DELETE", "/api/studies/{study_id}/members/{username}", {"params": ["study_id", "username"], "query": [], "body": false}),
  /**
   * PUT /api/studies/{study_id}/members: Give an account a role in the study (or change it,
   * or its site).
   * @param {number} studyId
   * @param {MemberIn} body
   * @returns {Promise<Array<MemberOut>>}
   */
  setMember: operation("studies.setMember", "PUT", "/api/studies/{study_id}/members", {"params": ["study_id"], "query": [], "body": true}),
  /**
   * PATCH /api/studies/{study_id}: Rename a study or change its description, withdrawal
   * policy or dataset description (authors, licence, institution: what its exports say about
   * the data).
   * @param {number} studyId
   * @param {StudyUpdate} body
   * @returns {Promise<StudyOut>}
   */
  update: operation("studies.update", "PATCH", "/api/studies/{study_id}", {"params": ["study_id"], "query": [], "body": true}),
});

export const trials = Object.freeze({
  /**
   * POST /api/trials/{trial_id}/segment: Propose the trial's lifts with the automatic
   * segmentation used for recordings. Segments the experimenter set are kept unless
   * `replace=true`. Where the ticks carry simulation labels they suggest each label;
   * otherwise segments are "unlabelled" and the results ignore the trial until they are
   * labelled.
   * @param {number} trialId
   * @param {{replace?: boolean}=} query
   * @returns {Promise<Array<TrialSegmentOut>>}
   */
  autoSegment: operation("trials.autoSegment", "POST", "/api/trials/{trial_id}/segment", {"params": ["trial_id"], "query": ["replace"], "body": false}),
  /**
   * GET /api/studies/{study_id}/export.zip: The whole study as a zip (see README.md inside
   * for every column's meaning).
   * @param {number} studyId
   * @returns {Promise<*>}
   */
  exportStudy: operation("trials.exportStudy", "GET", "/api/studies/{study_id}/export.zip", {"params": ["study_id"], "query": [], "body": false}),
  /**
   * GET /api/trials/{trial_id}: One trial with its configuration snapshot.
   * @param {number} trialId
   * @returns {Promise<TrialOut>}
   */
  get: operation("trials.get", "GET", "/api/trials/{trial_id}", {"params": ["trial_id"], "query": [], "body": false}),
  /**
   * GET /api/sessions/{session_id}/trials: The session's trials in planned order.
   * @param {number} sessionId
   * @returns {Promise<Array<TrialOut>>}
   */
  list: operation("trials.list", "GET", "/api/sessions/{session_id}/trials", {"params": ["session_id"], "query": [], "body": false}),
  /**
   * GET /api/trials/{trial_id}/segments: The trial's lift segments in time order.
   * @param {number} trialId
   * @returns {Promise<Array<TrialSegmentOut>>}
   */
  listTrialSegments: operation("trials.listTrialSegments", "GET", "/api/trials/{trial_id}/segments", {"params": ["trial_id"], "query": [], "body": false}),
  /**
   * POST /api/sessions/{session_id}/trials/plan: Create the session's trials: UMC and PEC in
   * the order this participant's place in the study gives (balanced across participants),
   * then E-UMC; each on every task. Also assigns the blinded labels the participant will
   * see.
   * @param {number} sessionId
   * @param {TrialPlanIn} body
   * @returns {Promise<Array<TrialOut>>}
   */
  plan: operation("trials.plan", "POST", "/api/sessions/{session_id}/trials/plan", {"params": ["session_id"], "query": [], "body": true}),
  /**
   * PUT /api/trials/{trial_id}/segments: Replace the trial's segments with this list (the
   * experimenter's checked lifts). Each must lie inside the trial's ticks and none may
   * overlap another; an empty list removes them all. Nothing changes if any segment is
   * refused.
   * @param {number} trialId
   * @param {Array<SegmentIn>} body
   * @returns {Promise<Array<TrialSegmentOut>>}
   */
  replaceTrialSegments: operation("trials.replaceTrialSegments", "PUT", "/api/trials/{trial_id}/segments", {"params": ["trial_id"], "query": [], "body": true}),
  /**
   * POST /api/trials/{trial_id}/start: Run the trial's controller with its model and utility
   * sets, at the session's precompression; the exact configuration is stored with the trial.
   * 409 while another trial or recording runs (checked and started under the runtime's
   * activity lock; the database's unique index refuses a second running trial in any case).
   * @param {number} trialId
   * @param {TrialStartIn} body
   * @returns {Promise<TrialOut>}
   */
  start: operation("trials.start", "POST", "/api/trials/{trial_id}/start", {"params": ["trial_id"], "query": [], "body": true}),
  /**
   * POST /api/trials/{trial_id}/stop: End the trial as completed or aborted; the worker
   * returns to recording mode (no locks); the trial's tick count, quality flags (device time
   * gaps, time going backwards) and lock events are derived from its stored ticks. 409 if it
   * is no longer running (e.g. `interrupted` because its worker stopped).
   * @param {number} trialId
   * @param {TrialStopIn} body
   * @returns {Promise<TrialOut>}
   */
  stop: operation("trials.stop", "POST", "/api/trials/{trial_id}/stop", {"params": ["trial_id"], "query": [], "body": true}),
  /**
   * GET /api/trials/{trial_id}/lock-events: The trial's lock events in time order.
   * @param {number} trialId
   * @returns {Promise<Array<LockEventOut>>}
   */
  trialLockEvents: operation("trials.trialLockEvents", "GET", "/api/trials/{trial_id}/lock-events", {"params": ["trial_id"], "query": [], "body": false}),
  /**
   * GET /api/trials/{trial_id}/ticks.csv: Every tick of the trial as CSV (columns and units:
   * the study export's data dictionary); empty cells are values not computed at that tick.
   * @param {number} trialId
   * @returns {Promise<*>}
   */
  trialTicksCsv: operation("trials.trialTicksCsv", "GET", "/api/trials/{trial_id}/ticks.csv", {"params": ["trial_id"], "query": [], "body": false}),
  /**
   * GET /api/trials/{trial_id}/ticks.json: Every tick of the trial as JSON columns (`field
   * -> list`, null where not computed).
   * @param {number} trialId
   * @returns {Promise<TickColumnsOut>}
   */
  trialTicksJson: operation("trials.trialTicksJson", "GET", "/api/trials/{trial_id}/ticks.json", {"params": ["trial_id"], "query": [], "body": false}),
});

export const vocabulary = Object.freeze({
  /**
   * GET /api/vocabulary: Tick columns, models, actions, flag bits, controllers, scripts,
   * health fields.
   * @returns {Promise<Vocabulary>}
   */
  vocabularyJson: operation("vocabulary.vocabularyJson", "GET", "/api/vocabulary", {"params": [], "query": [], "body": false}),
});

export const wearers = Object.freeze({
  /**
   * GET /api/participants/{participant_id}/progress: The wearer's long-use sessions in time
   * order and, per metric (lifts per hour, recognition and lock rates, time to lock, false
   * positives per hour of walking and of stairs), each session's value with its 95 %
   * interval and the least-squares trend per session with its 95 % interval. 409 for a
   * withdrawn participant.
   * @param {number} participantId
   * @param {{controller?: (string|null)}=} query
   * @returns {Promise<WearerProgressOut>}
   */
  getProgress: operation("wearers.getProgress", "GET", "/api/participants/{participant_id}/progress", {"params": ["participant_id"], "query": ["controller"], "body": false}),
  /**
   * POST /api/sessions/{session_id}/long-use: Run a controller for the wearer's work in a
   * long-use session: a trial of task `long_use` is added and started as a planned trial
   * starts (its own run, every tick and decision stored, the configuration snapshot). Stop
   * it with `POST /api/trials/{id}/stop`; mark events with `POST
   * /api/sessions/{id}/markers`. 409 if the session is not a long-use session or something
   * already runs.
   * @param {number} sessionId
   * @param {LongUseStartIn} body
   * @returns {Promise<TrialOut>}
   */
  startLongUse: operation("wearers.startLongUse", "POST", "/api/sessions/{session_id}/long-use", {"params": ["session_id"], "query": [], "body": true}),
});

export const worker = Object.freeze({
  /**
   * POST /api/worker/calibrate: E-UMC calibration: record the next seconds of standing still
   * and compute the offsets that map the rest posture onto the models' start. A running
   * E-UMC takes them at once; an E-UMC chosen later gets them too. 409 during a trial (a
   * running E-UMC taking new offsets would change the trial's controller).
   * @param {CalibrationRequest} body
   * @returns {Promise<CalibrationOutcome>}
   */
  calibrate: operation("worker.calibrate", "POST", "/api/worker/calibrate", {"params": [], "query": [], "body": true}),
  /**
   * GET /api/worker/controllers: Controllers the worker can run.
   * @returns {Promise<Array<string>>}
   */
  controllers: operation("worker.controllers", "GET", "/api/worker/controllers", {"params": [], "query": [], "body": false}),
  /**
   * POST /api/worker/restart: Start the worker again (stopping it first if it still runs).
   * @returns {Promise<Health>}
   */
  restart: operation("worker.restart", "POST", "/api/worker/restart", {"params": [], "query": [], "body": false}),
  /**
   * POST /api/worker/controller: Switch controller; a new run starts in the database.
   * `config` overrides controller settings (rates, thresholds, priors: see
   * `controller.config.ControllerConfig`). 409 while a trial or recording runs: its
   * controller is the one it was started with.
   * @param {ControllerChoice} body
   * @returns {Promise<Health>}
   */
  setController: operation("worker.setController", "POST", "/api/worker/controller", {"params": [], "query": [], "body": true}),
  /**
   * POST /api/worker/simulation: Change the simulated wearer (seed) or script; a new run
   * starts on the new one. 409 while a trial or recording runs; 503 if the device process
   * cannot start.
   * @param {SimulationChoice} body
   * @returns {Promise<Health>}
   */
  setSimulation: operation("worker.setSimulation", "POST", "/api/worker/simulation", {"params": [], "query": [], "body": true}),
  /**
   * POST /api/worker/stop: Release the device and stop the worker.
   * @returns {Promise<Health>}
   */
  stop: operation("worker.stop", "POST", "/api/worker/stop", {"params": [], "query": [], "body": false}),
});

/** The WebSocket paths, by route name. */
export const sockets = Object.freeze({"live": "/ws/live"});

// The live WebSocket: its path and its messages (backend/schemas/live.py and
// backend/schemas/lab.py), as typedefs and as the fields each `type` carries.

/**
 * The tick writer.
 * @typedef {object} DatabaseHealth
 * @property {number} ticks_written
 * @property {number} write_failures
 * @property {string} last_error
 * @property {(number|null)} current_run_id
 * @property {number} backlog
 * @property {number} ticks_dropped
 */

/**
 * The exoskeleton link: the worker's `DeviceReport`, the configured kind, and the identity the device proved when the host joined it (None before, and without a link).
 * @typedef {object} DeviceHealth
 * @property {boolean} alive
 * @property {(number|null)} last_sample_age_s
 * @property {Array<string>} faults
 * @property {number} implausible_samples samples of the current run that failed a plausibility check (no lock taken)
 * @property {Object<string, number>} link_drops packets dropped by the UDP link since the worker started, by reason: host side (auth, replay, stale, version, ...) and, as the device reports them, device side (device_auth, device_replay, device_stale)
 * @property {string} kind
 * @property {(DeviceIdentity|null)} identity
 */

/**
 * Which device is on the link, as it proved with its CHALLENGE: what hardware profiles are bound to. `unique_id` is 32 lowercase hex digits (the processor's id or a simulator's configured one), `firmware` its name and version, `key_id` names the link key (16 hex digits, `controller.device.auth.key_id`), `device_session` the device's boot session.
 * @typedef {object} DeviceIdentity
 * @property {string} unique_id
 * @property {string} firmware
 * @property {string} key_id
 * @property {number} device_session
 */

/**
 * One channel's live quality, as the EMG strip shows it (`backend.emg.live_envelope`).
 * @typedef {object} EmgChannelFlags
 * @property {boolean} clipping samples at the channel's rails in the last 0.5 s
 * @property {boolean} flat RMS below 0.1 uV in the last 0.5 s (electrode off?)
 * @property {number} non_finite NaN or infinite samples since the stream connected
 */

/**
 * `GET /api/health`: is the live path working?
 * @typedef {object} Health
 * @property {("ok"|"degraded")} status
 * @property {WorkerHealth} worker
 * @property {DeviceHealth} device
 * @property {DatabaseHealth} database
 * @property {number} clients
 * @property {string} version
 */

/**
 * The causal EMG envelope of a subscribed stream's channels, decimated for display (sent as samples arrive, at most 25 messages a second per stream).
 * @typedef {object} LiveEmg
 * @property {"emg"} type
 * @property {number} session_id
 * @property {number} subscription_id
 * @property {(number|null)} recording_id
 * @property {number} fs rate of `values` (Hz): the display rate
 * @property {Array<number>} t session (LSL) clock of each value, s
 * @property {number} t_end session clock of the newest raw sample taken, s
 * @property {number} clock_correction_s liblsl's estimate of this server's clock minus the amplifier's, added to its stamps (t_end - clock_correction_s is the amplifier's own stamp)
 * @property {number} sent_at server Unix time when the message was queued
 * @property {Array<string>} labels the montage's channel labels, in order
 * @property {Array<Array<number>>} values per channel: the envelope in volts
 * @property {Array<EmgChannelFlags>} flags
 */

/**
 * `/ws/live`: a marker was stored; consoles draw it at tick time `t` of `run_id`.
 * @typedef {object} LiveMarker
 * @property {"marker"} type
 * @property {MarkerOut} marker
 */

/**
 * Sent on connect, on every worker change and once a second.
 * @typedef {object} LiveStatus
 * @property {"status"} type
 * @property {Health} health
 */

/**
 * All ticks since the previous message, column by column (NaN sent as null).
 * @typedef {object} LiveTicks
 * @property {"ticks"} type
 * @property {number} msg_seq per-connection message counter; a jump means drops
 * @property {number} sent_at server Unix time when the message was queued
 * @property {(number|null)} run_id
 * @property {number} dropped messages dropped for this connection so far
 * @property {Object<string, Array<(number|number|boolean|string|null)>>} columns
 */

/**
 * A stored marker. `t` is the tick time (device clock) of the run `run_id`; `lsl_time` the same instant on the LSL clock.
 * @typedef {object} MarkerOut
 * @property {number} id
 * @property {number} session_id
 * @property {(number|null)} trial_id
 * @property {(number|null)} run_id
 * @property {(number|null)} t
 * @property {(number|null)} lsl_time
 * @property {string} label
 * @property {string} note
 * @property {string} source
 * @property {(number|null)} stream_id
 * @property {string} created_at
 */

/**
 * The worker as the server sees it: its last `LoopReport` and the process.
 * @typedef {object} WorkerHealth
 * @property {(string|null)} controller
 * @property {number} ticks
 * @property {(number|null)} period_mean_ms
 * @property {(number|null)} jitter_p50_ms
 * @property {(number|null)} jitter_p99_ms
 * @property {(number|null)} jitter_max_ms
 * @property {(number|null)} compute_p50_us
 * @property {(number|null)} compute_p99_us
 * @property {(number|null)} compute_max_us
 * @property {number} overruns
 * @property {number} gaps
 * @property {number} timeouts reads that waited for a sample in vain
 * @property {number} dropped_records ticks the worker dropped because the server did not take them
 * @property {boolean} alive
 * @property {(number|null)} pid
 * @property {number} restarts
 * @property {(number|null)} exit_code
 * @property {string} exit_reason
 * @property {Array<string>} errors
 */

/** @typedef {LiveTicks | LiveStatus | LiveMarker | LiveEmg} LiveMessage */

/** The fields of each live message, by its `type`. */
export const LIVE_MESSAGES = Object.freeze({"ticks": ["type", "msg_seq", "sent_at", "run_id", "dropped", "columns"], "status": ["type", "health"], "marker": ["type", "marker"], "emg": ["type", "session_id", "subscription_id", "recording_id", "fs", "t", "t_end", "clock_correction_s", "sent_at", "labels", "values", "flags"]});

/** A live message from its JSON text, checked against LIVE_MESSAGES.
 * @type {(text: string) => LiveMessage} */
export const readLiveMessage = messageReader(LIVE_MESSAGES);
