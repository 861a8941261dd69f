// Login when the API requires tokens (see core/api/src/auth.rs). Without auth (whoami
// says `auth: false`) nothing here shows and the dashboard is as it always was.
// The token lives in sessionStorage (this tab only, gone when it closes); the role is
// put on <body data-role> so style.css hides the controls it cannot use.
import * as api from './api.js';

const $ = (id) => document.getElementById(id);

function showLogin(error) {
  const box = $('login');
  if (!box.hidden) return;
  box.hidden = false;
  $('login-error').textContent = api.getToken() ? (error && error.error) || 'the token was refused' : '';
  $('login-token').focus();
}

async function tryLogin(ev) {
  ev.preventDefault();
  const token = $('login-token').value.trim();
  if (!token) return;
  let res;
  try {
    res = await fetch('/api/v1/auth/whoami', { headers: { Authorization: `Bearer ${token}` } });
  } catch (e) {
    $('login-error').textContent = `network error: ${e.message || e}`;
    return;
  }
  if (res.ok) {
    api.setToken(token);
    window.location.reload(); // everything (stream, video, pollers) starts again with it
    return;
  }
  const body = await res.json().catch(() => ({}));
  $('login-error').textContent = body.error || `HTTP ${res.status}`;
}

function logout() {
  api.clearToken();
  window.location.reload();
}

/** Asks who we are; shows the login on 401, the name and role otherwise. */
export async function initAuth() {
  api.auth.onUnauthorized = showLogin;
  $('login-form').addEventListener('submit', tryLogin);
  $('auth-logout').addEventListener('click', logout);
  const res = await api.request('GET', '/auth/whoami');
  if (!res.ok || !res.data || !res.data.auth) return; // 401: the login is up already
  document.body.dataset.role = res.data.role;
  $('auth-name').textContent = res.data.name;
  $('auth-role').textContent = res.data.role;
  $('auth-who').hidden = false;
}
