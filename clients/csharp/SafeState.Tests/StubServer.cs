// A minimal WebSocket server (RFC 6455) on a free loopback port that plays a script, so
// tests can send the client what no real gateway would: invalid JSON, unknown fields,
// oversize and binary frames, invalid UTF-8, replies to seqs never sent, an abrupt close.
using System;
using System.Collections.Generic;
using System.IO;
using System.Net;
using System.Net.Sockets;
using System.Security.Cryptography;
using System.Text;
using System.Threading.Tasks;

namespace SafeState.Tests
{
    internal sealed class StubServer : IDisposable
    {
        private readonly TcpListener listener;
        private TcpClient client;
        private Stream stream;

        public StubServer()
        {
            listener = new TcpListener(IPAddress.Loopback, 0);
            listener.Start();
        }

        public Uri Ws { get { return new Uri("ws://127.0.0.1:" + ((IPEndPoint)listener.LocalEndpoint).Port + "/ws"); } }

        /// <summary>Accepts one client and completes its upgrade.</summary>
        public async Task AcceptAsync()
        {
            client = await listener.AcceptTcpClientAsync().ConfigureAwait(false);
            stream = client.GetStream();
            string head = await ReadHead().ConfigureAwait(false);
            string key = null;
            foreach (string line in head.Split(new[] { "\r\n" }, StringSplitOptions.None))
            {
                if (line.StartsWith("Sec-WebSocket-Key:", StringComparison.OrdinalIgnoreCase)) key = line.Substring(18).Trim();
            }
            if (key == null) throw new IOException("no Sec-WebSocket-Key in " + head);
            string accept;
            using (var sha = SHA1.Create())
            {
                accept = Convert.ToBase64String(sha.ComputeHash(Encoding.ASCII.GetBytes(key + "258EAFA5-E914-47DA-95CA-C5AB0DC85B11")));
            }
            byte[] answer = Encoding.ASCII.GetBytes("HTTP/1.1 101 Switching Protocols\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n" +
                                                    "Sec-WebSocket-Accept: " + accept + "\r\n\r\n");
            await stream.WriteAsync(answer, 0, answer.Length).ConfigureAwait(false);
        }

        private async Task<string> ReadHead()
        {
            var head = new List<byte>();
            var one = new byte[1];
            while (head.Count < 8192)
            {
                if (await stream.ReadAsync(one, 0, 1).ConfigureAwait(false) != 1) throw new IOException("closed during the upgrade");
                head.Add(one[0]);
                int n = head.Count;
                if (n >= 4 && head[n - 4] == '\r' && head[n - 3] == '\n' && head[n - 2] == '\r' && head[n - 1] == '\n') break;
            }
            return Encoding.ASCII.GetString(head.ToArray());
        }

        /// <summary>The next text frame from the client (unmasked), or null on close.</summary>
        public async Task<string> ReceiveAsync()
        {
            while (true)
            {
                byte[] h = await Exactly(2).ConfigureAwait(false);
                int opcode = h[0] & 0x0F;
                long len = h[1] & 0x7F;
                if (len == 126) { byte[] e = await Exactly(2).ConfigureAwait(false); len = (e[0] << 8) | e[1]; }
                else if (len == 127)
                {
                    byte[] e = await Exactly(8).ConfigureAwait(false);
                    len = 0;
                    for (int i = 0; i < 8; ++i) len = (len << 8) | e[i];
                }
                byte[] mask = (h[1] & 0x80) != 0 ? await Exactly(4).ConfigureAwait(false) : new byte[4];
                byte[] payload = await Exactly((int)len).ConfigureAwait(false);
                for (int i = 0; i < payload.Length; ++i) payload[i] ^= mask[i % 4];
                if (opcode == 8) return null;
                if (opcode == 1) return Encoding.UTF8.GetString(payload);
            }
        }

        private async Task<byte[]> Exactly(int n)
        {
            var b = new byte[n];
            int got = 0;
            while (got < n)
            {
                int r = await stream.ReadAsync(b, got, n - got).ConfigureAwait(false);
                if (r == 0) throw new IOException("the client closed");
                got += r;
            }
            return b;
        }

        public Task SendText(string text) { return SendFrame(1, Encoding.UTF8.GetBytes(text)); }
        public Task SendBinary(byte[] data) { return SendFrame(2, data); }
        public Task SendRawText(byte[] bytes) { return SendFrame(1, bytes); }

        public async Task SendFrame(int opcode, byte[] payload)
        {
            var h = new List<byte> { (byte)(0x80 | opcode) };
            if (payload.Length < 126) h.Add((byte)payload.Length);
            else if (payload.Length < 65536) { h.Add(126); h.Add((byte)(payload.Length >> 8)); h.Add((byte)payload.Length); }
            else
            {
                h.Add(127);
                for (int i = 7; i >= 0; --i) h.Add((byte)((long)payload.Length >> (8 * i)));
            }
            byte[] head = h.ToArray();
            await stream.WriteAsync(head, 0, head.Length).ConfigureAwait(false);
            await stream.WriteAsync(payload, 0, payload.Length).ConfigureAwait(false);
            await stream.FlushAsync().ConfigureAwait(false);
        }

        /// <summary>Drops the TCP connection without a close frame (a crashed server).</summary>
        public void Drop()
        {
            if (client != null) client.Close();
        }

        public void Dispose()
        {
            Drop();
            listener.Stop();
        }
    }
}
