// The JSON API client of the ChakaMo UI (contract: /api/v1, see app/api).
//
// Decisions: the browser authenticates with the HttpOnly session cookie set by POST /auth/login; every
// state-changing request carries the X-CSRF-Token header with the token returned by login and /auth/me
// (kept in memory only, never in storage).  Errors are RFC 7807 problems (application/problem+json,
// app/web/problems.py) and become ApiError with the server's `detail` sentence (or, when the answer carries it,
// its `message` in the UI's language) so views can show it as is, and the problem's `code` and body for views
// that tell refusals apart; a 401 also calls the handler registered with onUnauthorized (back to login).
// Uploads use XMLHttpRequest instead of fetch, which cannot report upload progress.  Every request says the UI's
// language (Accept-Language), so the server's refusals of logins, passwords and accounts come back in it.

import { lang } from "./i18n.js";

const BASE = "/api/v1";
let csrfToken = null;
let unauthorizedHandler = null;

export class ApiError extends Error {
  constructor(status, detail, problem = null) {
    super(detail);
    this.status = status;
    this.detail = detail;
    this.problem = problem;                      // the problem body, when the answer was one
    this.code = problem && problem.code ? problem.code : null;
  }
}

/** Remember the CSRF token of the logged-in browser session (null on logout). */
export function setCsrf(token) {
  csrfToken = token || null;
}

/** Register `fn(error)` called on every 401 answer. */
export function onUnauthorized(fn) {
  unauthorizedHandler = fn;
}

/** The URL of an API path with query parameters (null/undefined values skipped). */
export function apiUrl(path, query = {}) {
  const params = new URLSearchParams();
  for (const [k, v] of Object.entries(query)) if (v !== null && v !== undefined && v !== "") params.set(k, v);
  const qs = params.toString();
  return `${BASE}${path}${qs ? `?${qs}` : ""}`;
}

function detailText(body, status, statusText) {
  // a refusal the server has in es/en/pt (app/web/refusals.py) is shown in the UI's language
  const translated = body && typeof body === "object" && body.message && typeof body.message === "object"
    ? body.message[lang()] : null;
  if (typeof translated === "string" && translated) return translated;
  const detail = body && typeof body === "object" ? body.detail : null;
  if (typeof detail === "string") return detail;
  if (typeof body === "string" && body.trim()) return body.trim().slice(0, 300);
  return `HTTP ${status} ${statusText || ""}`.trim();
}

function fail(status, body, statusText) {
  const problem = body && typeof body === "object" && typeof body.status === "number" && body.title ? body : null;
  const err = new ApiError(status, detailText(body, status, statusText), problem);
  if (status === 401 && unauthorizedHandler) unauthorizedHandler(err);
  throw err;
}

/** Call the API: `await api("POST", "/patients", {json: {...}})`; returns the parsed JSON (null for 204).
 *  `ifMatch`: the version a correction or erasure was based on (sent as `If-Match: "<version>"`). */
export async function api(method, path, { json, query, ifMatch } = {}) {
  const headers = { Accept: "application/json, application/problem+json", "Accept-Language": lang() };
  if (ifMatch !== undefined && ifMatch !== null) headers["If-Match"] = `"${ifMatch}"`;
  const init = { method, headers, credentials: "same-origin" };
  if (json !== undefined) {
    headers["Content-Type"] = "application/json";
    init.body = JSON.stringify(json);
  }
  if (!["GET", "HEAD"].includes(method) && csrfToken) headers["X-CSRF-Token"] = csrfToken;
  let res;
  try {
    res = await fetch(apiUrl(path, query), init);
  } catch (e) {
    throw new ApiError(0, e.message);
  }
  if (res.status === 204) return null;
  const type = res.headers.get("Content-Type") || "";
  const body = type.includes("json") ? await res.json().catch(() => null) : await res.text();
  if (!res.ok) fail(res.status, body, res.statusText);
  return body;
}

/** POST a multipart form to `path`, calling onProgress(fraction) while the body is sent; resolves to JSON. */
export function upload(path, formData, onProgress = () => {}) {
  return new Promise((resolve, reject) => {
    const xhr = new XMLHttpRequest();
    xhr.open("POST", apiUrl(path));
    xhr.setRequestHeader("Accept", "application/json, application/problem+json");
    xhr.setRequestHeader("Accept-Language", lang());
    if (csrfToken) xhr.setRequestHeader("X-CSRF-Token", csrfToken);
    xhr.upload.addEventListener("progress", (e) => { if (e.lengthComputable) onProgress(e.loaded / e.total); });
    xhr.addEventListener("load", () => {
      let body = xhr.responseText;
      try { body = JSON.parse(xhr.responseText); } catch (_) { /* not JSON: keep the text */ }
      if (xhr.status >= 200 && xhr.status < 300) resolve(body);
      else {
        try { fail(xhr.status, body, xhr.statusText); } catch (e) { reject(e); }
      }
    });
    xhr.addEventListener("error", () => reject(new ApiError(0, "network error")));
    xhr.send(formData);
  });
}
