// The event history and the active alarm list over HTTP (protocol.md GET /api/events and
// GET /api/alarms), read as strictly as the WebSocket messages.
using System;
using System.Collections.Generic;
using System.Globalization;
using System.Net.Http;
using System.Net.Http.Headers;
using System.Threading.Tasks;

namespace SafeState.Client
{
    public sealed class HistoryClient : IDisposable
    {
        /// <summary>The server clamps a page to this many events.</summary>
        public const int MaxPage = 500;
        private const int MaxBody = 16 * 1024 * 1024;

        private readonly Uri baseUri;
        private readonly HttpClient http;

        /// <param name="baseUri">http://HOST:PORT/ of the gateway.</param>
        /// <param name="bearerToken">Needed when the gateway listens beyond loopback (protocol.md).</param>
        public HistoryClient(Uri baseUri, string bearerToken = null)
        {
            if (baseUri == null) throw new ArgumentNullException("baseUri");
            this.baseUri = baseUri;
            http = new HttpClient { Timeout = TimeSpan.FromSeconds(10), MaxResponseContentBufferSize = MaxBody };
            if (!string.IsNullOrEmpty(bearerToken))
            {
                http.DefaultRequestHeaders.Authorization = new AuthenticationHeaderValue("Bearer", bearerToken);
            }
        }

        /// <summary>The HTTP base of a ws://HOST:PORT/ws URL.</summary>
        public static Uri BaseOf(Uri webSocketUri)
        {
            var b = new UriBuilder(webSocketUri) { Scheme = webSocketUri.Scheme == "wss" ? "https" : "http", Path = "/", Query = "" };
            return b.Uri;
        }

        /// <summary>At most `limit` events with id greater than `after`, oldest first.</summary>
        public async Task<IReadOnlyList<EventMessage>> GetEventsAsync(long after, int limit = 100)
        {
            if (after < 0) throw new ArgumentOutOfRangeException("after");
            if (limit < 1 || limit > MaxPage) throw new ArgumentOutOfRangeException("limit", limit, "1.." + MaxPage);
            List<object> items = await GetArray(string.Format(CultureInfo.InvariantCulture, "api/events?after={0}&limit={1}", after, limit))
                .ConfigureAwait(false);
            var list = new List<EventMessage>();
            foreach (object o in items) list.Add(EventMessage.Read(new Fields(o, "event"), true));
            return list;
        }

        public async Task<IReadOnlyList<AlarmEntry>> GetAlarmsAsync()
        {
            List<object> items = await GetArray("api/alarms").ConfigureAwait(false);
            var list = new List<AlarmEntry>();
            foreach (object o in items) list.Add(AlarmEntry.Read(new Fields(o, "alarm")));
            return list;
        }

        /// <summary>A pager that walks the history forward from `after`.</summary>
        public EventPager Events(long after = 0, int pageSize = 100)
        {
            return new EventPager(this, after, pageSize);
        }

        /// <summary>The black box of a stop event (the cycles before it), as the gateway
        /// serves it at the event's BlackBoxUrl; null when the event has none.</summary>
        public async Task<object> GetBlackBoxAsync(EventMessage e)
        {
            if (e == null) throw new ArgumentNullException("e");
            if (e.BlackBoxUrl == null) return null;
            if (!e.BlackBoxUrl.StartsWith("/api/events/", StringComparison.Ordinal))
                throw new MessageException("blackbox: not an /api/events/ address: " + e.BlackBoxUrl);
            return await GetJson(e.BlackBoxUrl.Substring(1)).ConfigureAwait(false);
        }

        private async Task<List<object>> GetArray(string path)
        {
            var items = await GetJson(path).ConfigureAwait(false) as List<object>;
            if (items == null) throw new MessageException("GET /" + path + ": expected a JSON array");
            return items;
        }

        private async Task<object> GetJson(string path)
        {
            using (HttpResponseMessage r = await http.GetAsync(new Uri(baseUri, path)).ConfigureAwait(false))
            {
                string body = await r.Content.ReadAsStringAsync().ConfigureAwait(false);
                if (!r.IsSuccessStatusCode)
                {
                    throw new MessageException("GET /" + path + ": HTTP " + (int)r.StatusCode + " " + body);
                }
                MediaTypeHeaderValue type = r.Content.Headers.ContentType;
                if (type == null || type.MediaType != "application/json")
                {
                    throw new MessageException("GET /" + path + ": not JSON (" + type + ")");
                }
                try
                {
                    return Json.Parse(body);
                }
                catch (JsonException e)
                {
                    throw new MessageException("GET /" + path + ": " + e.Message);
                }
            }
        }

        public void Dispose()
        {
            http.Dispose();
        }
    }

    /// <summary>Pages through /api/events; each NextAsync continues after the last id seen.</summary>
    public sealed class EventPager
    {
        private readonly HistoryClient history;
        private readonly int pageSize;

        internal EventPager(HistoryClient history, long after, int pageSize)
        {
            this.history = history;
            After = after;
            this.pageSize = pageSize;
        }

        /// <summary>The id the next page starts after.</summary>
        public long After { get; private set; }

        /// <summary>The next page; empty when the history has no newer event yet.</summary>
        public async Task<IReadOnlyList<EventMessage>> NextAsync()
        {
            IReadOnlyList<EventMessage> page = await history.GetEventsAsync(After, pageSize).ConfigureAwait(false);
            foreach (EventMessage e in page)
            {
                if (!e.Id.HasValue || e.Id.Value <= After)
                {
                    throw new MessageException("/api/events: ids must grow (got " + e.Id + " after " + After + ")");
                }
                After = e.Id.Value;
            }
            return page;
        }
    }
}
